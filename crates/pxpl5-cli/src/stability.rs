//! `pxpl5 stability`: where the machine's form factors break, as a study. One point-to-polygon
//! form factor (`pxpl5 formfactor`'s computation, `experiment::form_factor`) is measured on the
//! machine with each method and set against the exact value, while one thing moves:
//!
//! - `qee_frac_bits`: the QEE coefficients' fractional bits, 4 to 32. The QEE tree must fit
//!   64-bit arithmetic (int + frac + 1 + 2 x coordinate bits + 3 <= 64), so past 23 fractional
//!   bits the integer bits shrink to make room (the row's note says to what).
//! - `scale`: the whole geometry (point and polygon) times 1e-9 to 1e9: the form factor does not
//!   change, so any error beyond the scale-1 one is the arithmetic's.
//! - `elevation_deg`: a small square facing the point, its centre from the pole (90 degrees above
//!   the point's horizon) down to 0.01 degrees above the horizon.
//!
//! Writes OUT/stability.csv (a row per study, value and method) and OUT/stability.svg (the error
//! against each study's quantity); prints the table. Every figure is simulated, so both files are
//! the same bytes on every run.

use std::path::PathBuf;

use clap::Args;
use pxpl5_config::MachineConfig;
use pxpl5_geom::DVec3;
use pxpl5_machine::RunOptions;
use pxpl5_radiosity::experiment;
use pxpl5_radiosity::shot::{FfOptions, Method, check_resolution};

use crate::UserError;
use crate::choices::Methods;
use crate::config_cmd;
use crate::failure::Failure;
use crate::output::{self, out, outln};
use crate::plot::{self, Table};
use crate::radiosity::number;

/// Options of `pxpl5 stability`.
#[derive(Args, Clone, Debug)]
pub struct StabilityArgs {
    /// Machine config (RON); default: the embedded seed machine.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Form-factor methods measured.
    #[arg(long, value_enum, default_value_t = Methods::Both)]
    pub method: Methods,
    /// Pixels across the hemisphere's disk and the hemicube's top face.
    #[arg(long, default_value_t = 128)]
    pub resolution: u32,
    /// Output directory.
    #[arg(long, default_value = "out/stability")]
    pub out: PathBuf,
}

/// One measurement: a study's value, a method, the machine's form factor (or why there is none)
/// and the exact one.
struct Row {
    study: &'static str,
    x: f64,
    method: Method,
    machine: Result<f64, String>,
    exact: f64,
    note: String,
}

impl Row {
    fn error(&self) -> Option<f64> {
        let m = self.machine.as_ref().ok()?;
        (self.exact != 0.0).then(|| (m - self.exact).abs() / self.exact.abs())
    }
}

/// A square of side `side` whose centre is at `distance` from the origin, `elevation` degrees
/// above the xy plane (the horizon of a point at the origin with normal +z), facing the origin.
fn facing_square(elevation_deg: f64, distance: f64, side: f64) -> Vec<DVec3> {
    let e = elevation_deg.to_radians();
    let dir = DVec3::new(e.cos(), 0.0, e.sin());
    let centre = dir * distance;
    // Two axes across the square, perpendicular to the direction to it.
    let u = DVec3::new(0.0, 1.0, 0.0);
    let v = dir.cross(u);
    let h = side / 2.0;
    vec![
        centre - u * h - v * h,
        centre + u * h - v * h,
        centre + u * h + v * h,
        centre - u * h + v * h,
    ]
}

/// The seed machine's QEE with `frac` fractional bits, and integer bits narrowed where the 64-bit
/// tree needs it; `None` when no integer bits are left.
fn with_frac_bits(cfg: &MachineConfig, frac: u32) -> Option<(MachineConfig, String)> {
    let mut c = cfg.clone();
    let q = &mut c.renderer.qee;
    let room = 64u32.checked_sub(3 + 2 * q.coordinate_bits + 1 + frac)?;
    let mut note = String::new();
    if q.coefficient_format.int_bits > room {
        note = format!(
            "int_bits {} (from {}), so that the QEE tree fits 64 bits",
            room, q.coefficient_format.int_bits
        );
        q.coefficient_format.int_bits = room;
    }
    if q.coefficient_format.int_bits == 0 {
        return None;
    }
    q.coefficient_format.frac_bits = frac;
    Some((c, note))
}

/// `pxpl5 stability`.
pub fn stability(args: &StabilityArgs) -> Result<(), Failure> {
    let cfg = config_cmd::load(args.config.as_deref())?;
    let methods = args.method.methods();
    for &m in &methods {
        check_resolution(m, args.resolution, &cfg.renderer)
            .map_err(|e| UserError(format!("--resolution {}: {e}", args.resolution)))?;
    }
    output::check_dir("--out", &args.out)?;
    let normal = DVec3::Z;
    let measure = |cfg: &MachineConfig, method, point: DVec3, polygon: Vec<DVec3>| {
        let options = FfOptions {
            method,
            resolution: args.resolution,
            ..FfOptions::default()
        };
        experiment::form_factor(cfg, point, normal, polygon, options, RunOptions::default())
            .map(|r| r.form_factor)
            .map_err(|e| e.to_string())
    };
    let mut rows = Vec::new();
    // The QEE's fractional bits, on a square at 45 degrees.
    let square = facing_square(45.0, 1.0, 0.5);
    let exact45 = pxpl5_radiosity::exact::point_to_polygon(DVec3::ZERO, normal, &square);
    for frac in [4, 8, 12, 16, 20, 24, 28, 32] {
        for &method in &methods {
            let (machine, note) = match with_frac_bits(&cfg, frac) {
                Some((c, note)) => match config_cmd::check_changed("the QEE of this study", &c) {
                    Ok(()) => (measure(&c, method, DVec3::ZERO, square.clone()), note),
                    Err(e) => (Err(e.0.lines().last().unwrap_or("").to_string()), note),
                },
                None => (
                    Err("no integer bits left in a 64-bit QEE tree".to_string()),
                    String::new(),
                ),
            };
            rows.push(Row {
                study: "qee_frac_bits",
                x: f64::from(frac),
                method,
                machine,
                exact: exact45,
                note,
            });
        }
    }
    // The scale of the whole geometry.
    for k in [-9, -6, -3, 0, 3, 6, 9] {
        let s = 10f64.powi(k);
        let offset = DVec3::new(0.3, 0.2, 0.0);
        let point = offset * s;
        let polygon: Vec<DVec3> = square.iter().map(|&v| (v + offset) * s).collect();
        let exact = pxpl5_radiosity::exact::point_to_polygon(point, normal, &polygon);
        for &method in &methods {
            rows.push(Row {
                study: "scale",
                x: s,
                method,
                machine: measure(&cfg, method, point, polygon.clone()),
                exact,
                note: String::new(),
            });
        }
    }
    // From the pole to the horizon.
    for elevation in [90.0, 89.9, 89.0, 80.0, 45.0, 10.0, 1.0, 0.1, 0.01] {
        let polygon = facing_square(elevation, 1.0, 0.1);
        let exact = pxpl5_radiosity::exact::point_to_polygon(DVec3::ZERO, normal, &polygon);
        for &method in &methods {
            rows.push(Row {
                study: "elevation_deg",
                x: elevation,
                method,
                machine: measure(&cfg, method, DVec3::ZERO, polygon.clone()),
                exact,
                note: "a 0.1 square at distance 1 facing the point".into(),
            });
        }
    }
    let csv = stability_csv(&rows, args);
    let table = Table::parse(&args.out.join("stability.csv"), &csv)?;
    let svg = plot::svg(&plot::stability_charts(&table)?, (520, 420))?;
    crate::sweep::write_files(
        &args.out,
        vec![
            ("stability.csv".into(), csv.into_bytes()),
            ("stability.svg".into(), svg.into_bytes()),
        ],
    )?;
    out!("{}", stability_text(&rows))?;
    outln!("wrote {}/stability.csv, stability.svg", args.out.display())?;
    Ok(())
}

fn stability_csv(rows: &[Row], args: &StabilityArgs) -> String {
    let quote = |s: &str| format!("\"{}\"", s.replace('"', "\"\""));
    let mut csv = format!(
        "# pxpl5 {} stability: resolution {}\nstudy,x,method,form_factor,exact,ff_error,note\n",
        env!("CARGO_PKG_VERSION"),
        args.resolution
    );
    for r in rows {
        let (value, note) = match &r.machine {
            Ok(v) => (number(*v), r.note.clone()),
            Err(e) if r.note.is_empty() => (String::new(), e.clone()),
            Err(e) => (String::new(), format!("{}; {e}", r.note)),
        };
        csv += &format!(
            "{},{},{},{value},{},{},{}\n",
            r.study,
            number(r.x),
            r.method.name(),
            number(r.exact),
            r.error().map_or(String::new(), number),
            quote(&note)
        );
    }
    csv
}

fn stability_text(rows: &[Row]) -> String {
    let mut t = String::from(
        "Form factors on the machine against exact (relative error), at the extremes\n",
    );
    let mut study = "";
    for r in rows {
        if r.study != study {
            study = r.study;
            t += &format!("\n{study}\n");
        }
        let shown = match (&r.machine, r.error()) {
            (Ok(v), Some(e)) => format!("{v:.6e} (exact {:.6e}): error {e:.3e}", r.exact),
            (Ok(v), None) => format!("{v:.6e} (exact {:.6e})", r.exact),
            (Err(e), _) => format!("no value: {e}"),
        };
        t += &format!("  {:>10} {:<10} {shown}\n", number(r.x), r.method.name());
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The square faces the point and sits where asked: its centre's elevation and distance.
    #[test]
    fn squares_face_the_point_at_their_elevation() {
        for elevation in [90.0, 45.0, 0.01] {
            let sq = facing_square(elevation, 1.0, 0.1);
            let centre = sq.iter().fold(DVec3::ZERO, |a, &v| a + v) / 4.0;
            assert!((centre.length() - 1.0).abs() < 1e-12);
            let e = (centre.z / centre.length()).asin().to_degrees();
            assert!((e - elevation).abs() < 1e-9, "{e} {elevation}");
            let n = (sq[1] - sq[0]).cross(sq[2] - sq[1]).normalize();
            assert!((n.dot(centre.normalize()).abs() - 1.0).abs() < 1e-12);
        }
    }

    /// Past 23 fractional bits the integer bits give way, so the tree still fits 64 bits.
    #[test]
    fn wide_fractions_narrow_the_integer_part() {
        let cfg = pxpl5_config::default_config();
        let (c, note) = with_frac_bits(&cfg, 18).unwrap_or_else(|| panic!("fits"));
        assert_eq!(c, cfg);
        assert!(note.is_empty());
        let (c, note) = with_frac_bits(&cfg, 28).unwrap_or_else(|| panic!("fits"));
        let f = c.renderer.qee.coefficient_format;
        assert_eq!((f.int_bits, f.frac_bits), (8, 28));
        assert!(note.starts_with("int_bits 8 (from 13)"), "{note}");
        assert!(pxpl5_config::check("test", &c).is_ok());
    }
}
