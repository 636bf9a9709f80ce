//! Fuzz targets of the CLI's value parsers (see `pxpl5_tests::fuzzing`): `--point`, `--normal`
//! and `--polygon` (vectors and polygon checks, with the exact form factor of what they accept),
//! `--max-time` and `--trace-window` (times and windows), `--memory-limit` (sizes), the
//! finite-number options, and whole command lines through clap. Any text must give a value or
//! an error, never a panic; what is accepted satisfies the parser's own promise.

use clap::Parser;
use proptest::prelude::*;
use pxpl5_tests::fuzzing::{EXTREME_NUMBERS, config, extreme_f64};

use crate::Cli;
use crate::choices::FormFactorMethod;
use crate::radiosity::{FormFactorArgs, given, non_negative_finite, parse_v3, positive_finite};

/// A number as a user may type it: an extreme one, any f64, or a piece of garbage.
fn number_text() -> impl Strategy<Value = String> {
    prop_oneof![
        3 => extreme_f64().prop_map(|x| format!("{x:?}")),
        1 => prop::sample::select(EXTREME_NUMBERS).prop_map(str::to_string),
        1 => prop::sample::select(vec![
            "", " ", "-", "+", "e", "1e", "1e99999", "0x10", "١", "1,5", "1..2", "∞", "-0",
        ])
        .prop_map(str::to_string),
        1 => ".{0,12}",
    ]
}

/// `X,Y,Z` mostly, sometimes with a part too many or too few.
fn vector_text() -> impl Strategy<Value = String> {
    prop_oneof![
        6 => prop::collection::vec(number_text(), 3).prop_map(|v| v.join(",")),
        1 => prop::collection::vec(number_text(), 0..5).prop_map(|v| v.join(",")),
    ]
}

/// An ordinary vector mostly (so that the polygon checks are reached), else [`vector_text`].
fn ordinary_vector_text() -> impl Strategy<Value = String> {
    prop_oneof![
        4 => (-5.0f64..5.0, -5.0f64..5.0, -5.0f64..5.0).prop_map(|(x, y, z)| format!("{x},{y},{z}")),
        1 => vector_text(),
    ]
}

/// A polygon: mostly a convex one (3 to 7 corners on a circle of any size, on a plane of any
/// orientation and place, some corners perhaps moved off it), else 0 to 7 vectors of any text.
fn polygon_text() -> impl Strategy<Value = String> {
    let convex = (
        3usize..8,
        prop_oneof![3 => 0.01f64..10.0, 1 => extreme_f64()],
        (-5.0f64..5.0, -5.0f64..5.0, -5.0f64..5.0),
        (0.0f64..6.3, 0.0f64..3.2),
        prop::collection::vec((any::<bool>(), -1.0f64..1.0), 7),
    )
        .prop_map(|(n, r, (cx, cy, cz), (azimuth, tilt), moves)| {
            // The plane's two directions: u in the xy plane, v tilted out of it.
            let u = (azimuth.cos(), azimuth.sin(), 0.0);
            let v = (
                -azimuth.sin() * tilt.cos(),
                azimuth.cos() * tilt.cos(),
                tilt.sin(),
            );
            (0..n)
                .map(|k| {
                    let a = std::f64::consts::TAU * k as f64 / n as f64;
                    let (c, s) = (r * a.cos(), r * a.sin());
                    // One corner in four, now and then, moved off the plane or the circle.
                    let (moved, by) = moves[k];
                    let off = if moved && k % 4 == 0 { by * r } else { 0.0 };
                    let x = cx + c * u.0 + s * v.0;
                    let y = cy + c * u.1 + s * v.1;
                    let z = cz + c * u.2 + s * v.2 + off;
                    format!("{x},{y},{z}")
                })
                .collect::<Vec<_>>()
                .join(";")
        });
    prop_oneof![
        4 => convex,
        1 => prop::collection::vec(vector_text(), 0..8).prop_map(|v| v.join(";")),
    ]
}

/// A time as `--max-time` takes it: a number and a unit, or garbage.
fn time_text() -> impl Strategy<Value = String> {
    let unit = prop::sample::select(vec!["ps", "ns", "us", "ms", "s", "", "h", "S", " s", "µs"]);
    prop_oneof![
        3 => (number_text(), unit).prop_map(|(n, u)| format!("{n}{u}")),
        1 => ".{0,16}",
    ]
}

proptest! {
    #![proptest_config(config(20_000))]

    #[test]
    fn fuzz_cli_vectors(text in prop_oneof![vector_text(), ".{0,40}"]) {
        if let Ok(v) = parse_v3("--point", &text) {
            prop_assert!(v.is_finite());
        }
    }

    #[test]
    fn fuzz_cli_numbers(text in prop_oneof![number_text(), ".{0,20}"]) {
        if let Ok(x) = positive_finite(&text) {
            prop_assert!(x.is_finite() && x > 0.0);
        }
        if let Ok(x) = non_negative_finite(&text) {
            prop_assert!(x.is_finite() && x >= 0.0);
        }
    }

    #[test]
    fn fuzz_cli_times_and_windows(a in time_text(), b in time_text()) {
        let _ = pxpl5_trace::parse_time(&a);
        let window = format!("{a}..{b}");
        if let Ok(w) = pxpl5_trace::TraceWindow::parse(&window) {
            // Each side is a time, or empty (open).
            let side = |t: &str| {
                let t = t.trim();
                if t.is_empty() { Ok(None) } else { pxpl5_trace::parse_time(t).map(Some) }
            };
            let (start, end) = (side(&a), side(&b));
            prop_assert!(start.is_ok() && end.is_ok(), "{} accepted", window);
            let start = start.ok().flatten().unwrap_or_default();
            prop_assert!(w.contains(start), "{} misses its start", window);
            if let Ok(Some(end)) = end {
                prop_assert!(!w.contains(end) && start < end, "{} holds its end", window);
            }
        }
    }

    #[test]
    fn fuzz_cli_sizes(n in number_text(), unit in ".{0,4}") {
        let text = format!("{n}{unit}");
        if let Ok(bytes) = pxpl5_machine::memory::parse_size(&text) {
            prop_assert!(text.trim().starts_with(|c: char| c.is_ascii_digit()), "{}", text);
            prop_assert!(bytes >= n.trim().parse::<u64>().unwrap_or(0), "{}", text);
        }
    }
}

proptest! {
    // The polygon checks and the exact formula: about 20 us a case.
    #![proptest_config(config(5_000))]

    /// What `pxpl5 formfactor` accepts has an exact form factor: a finite number.
    #[test]
    fn fuzz_cli_formfactor_arguments(
        point in ordinary_vector_text(),
        normal in ordinary_vector_text(),
        polygon in polygon_text(),
    ) {
        let args = formfactor_args(point, normal, polygon);
        if let Ok(g) = given(&args) {
            let f = pxpl5_radiosity::exact::point_to_polygon(g.point, g.normal, &g.polygon);
            prop_assert!(f.is_finite(), "{:?} {:?} {:?}: {}", g.point, g.normal, g.polygon, f);
            prop_assert!(g.unit_normal.is_normalized());
        }
    }
}

/// `formfactor`'s options for the exact method with these texts, the others at their defaults.
fn formfactor_args(point: String, normal: String, polygon: String) -> FormFactorArgs {
    FormFactorArgs {
        point,
        normal,
        polygon,
        method: FormFactorMethod::Exact,
        resolution: 128,
        config: None,
        json: false,
        time_limit: crate::watch::parse_time_limit("10s").expect("a time"),
        host_time_limit: crate::watch::parse_host_limit(crate::watch::DEFAULT_HOST_LIMIT)
            .expect("the default limit"),
    }
}

/// Words of a command line: subcommands, every flag, and values good and bad.
const WORDS: &[&str] = &[
    "run",
    "radiosity",
    "formfactor",
    "config",
    "check",
    "show",
    "bench",
    "renderer",
    "--help",
    "-v",
    "-vv",
    "-q",
    "--memory-limit",
    "--config",
    "--scene",
    "--triangles",
    "--seed",
    "--out",
    "--trace",
    "--vcd",
    "--trace-window",
    "--fidelity",
    "--max-time",
    "--method",
    "--shots",
    "--threshold",
    "--patch-size",
    "--resolution",
    "--edge-rule",
    "--delta",
    "--all-faces",
    "--no-rotation",
    "--rotation-seed",
    "--shooters-at-once",
    "--depth",
    "--item-buffers",
    "--point",
    "--normal",
    "--polygon",
    "--json",
    "--repeat",
    "-",
    "--",
    "0",
    "1",
    "-1",
    "4096",
    "4294967296",
    "18446744073709551616",
    "NaN",
    "1e308",
    "bit",
    "integer",
    "word",
    "both",
    "hemisphere",
    "hemicube",
    "exact",
    "4GiB",
    "0..1ms",
    "1,2,3",
    "0,0,1",
    "é",
    "",
];

proptest! {
    #![proptest_config(config(20_000))]

    /// Any command line parses or is a usage error; parsing runs nothing.
    #[test]
    fn fuzz_cli_command_lines(words in prop::collection::vec(prop::sample::select(WORDS), 0..8)) {
        let _ = Cli::try_parse_from(std::iter::once("pxpl5").chain(words));
    }
}

/// The form-factor target reaches both paths: some arguments are accepted, some refused.
#[test]
fn fuzz_cli_formfactor_arguments_reach_both_paths() {
    let args = (
        ordinary_vector_text(),
        ordinary_vector_text(),
        polygon_text(),
    );
    let accepted = pxpl5_tests::fuzzing::count(&args, 1000, |(point, normal, polygon)| {
        given(&formfactor_args(
            point.clone(),
            normal.clone(),
            polygon.clone(),
        ))
        .is_ok()
    });
    assert!((50..950).contains(&accepted), "{accepted} of 1000 accepted");
}
