//! The host's watch over the simulations a command runs, so that no run can hang silently:
//!
//! - **Limits.** `--time-limit` (simulated time, checked by the machine at every event) and
//!   `--host-time-limit` (host time from the command's start, checked here) stop a run with a
//!   report of where it was: simulated time reached, shots done, the units still running; exit
//!   code 1 and nothing written.
//! - **Ctrl-C** (SIGINT; SIGTERM and SIGHUP alike): counted by a handler ([`catch_interrupts`]).
//!   The first asks each run what its [`Sim::interrupt`] says: `radiosity` ends after the shot
//!   under way (`Stop::Soon`) and writes what it computed, marked partial; `run` and
//!   `formfactor` stop at once (`Stop::Now`) and write nothing. The second stops any run at
//!   once; the third ends the process at once, exit code 130 in every case.
//! - **Work estimates** ([`estimate`]): before a run, its work is logged at info level, and at
//!   warn level when it is large.
//! - **Progress**: a bar on stderr (simulated time reached, shots done of those asked, simulated
//!   time per host second), only when stderr is a terminal, not with `-q`, and only once a run
//!   has taken [`SHOW_AFTER`]: pipes, files and tests see nothing. With `-v`, each shot done is
//!   also logged at info level.
//!
//! **Determinism.** The watcher is a second thread that looks at the run's `Monitor` every
//! [`POLL`] and may ask it to stop; it never changes what a run that is not stopped computes.
//! Host time is read here and only here: nothing a library returns depends on the host.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::{Arc, LazyLock};
use std::time::{Duration, Instant};

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use pxpl5_machine::{Monitor, RunError, RunOptions, Stop};
use pxpl5_sim::Tick;

use crate::failure::Failure;

/// How often the watcher looks at a run: the latency of a Ctrl-C or a host-time limit, and the
/// progress bar's refresh.
pub const POLL: Duration = Duration::from_millis(100);

/// A run shows a progress bar once it has taken this much host time: shorter runs draw nothing.
pub const SHOW_AFTER: Duration = Duration::from_secs(1);

/// The default `--host-time-limit`: generous (the main job takes seconds, the README's longest
/// examples about a minute), so that only a run that has gone astray, such as a machine of
/// thousands of units, meets it.
pub const DEFAULT_HOST_LIMIT: &str = "10min";

/// Interrupts (SIGINT, SIGTERM, SIGHUP) received so far.
static INTERRUPTS: AtomicU32 = AtomicU32::new(0);

/// The interrupt that ends the process at once, whatever it is doing.
const HARD_EXIT: u32 = 3;

/// Whether runs may show a progress bar: stderr is a terminal and `-q` was not given.
static PROGRESS: AtomicBool = AtomicBool::new(false);

/// The progress bars on screen: one per run under way (`radiosity` runs its methods at once), or
/// the command's own. Log lines are written around them ([`suspend`]).
static BARS: LazyLock<MultiProgress> =
    LazyLock::new(|| MultiProgress::with_draw_target(ProgressDrawTarget::stderr()));

/// Whether each run draws its own bar: a command that runs many at once (`sweep`) draws one bar
/// of its own instead ([`hide_run_bars`], [`command_bar`]).
static RUN_BARS: AtomicBool = AtomicBool::new(true);

/// Draw no per-run bars for the rest of the process: the command shows its own.
pub fn hide_run_bars() {
    RUN_BARS.store(false, Ordering::Relaxed);
}

/// A bar of `len` steps for the whole command, drawn with `template` (indicatif's) and `prefix`,
/// registered for [`suspend`]; `None` when progress is not shown (stderr is no terminal, `-q`).
/// [`finish_bar`] takes it off the screen.
pub fn command_bar(len: u64, prefix: &str, template: &str) -> Option<ProgressBar> {
    if !PROGRESS.load(Ordering::Relaxed) {
        return None;
    }
    let bar = BARS.add(ProgressBar::new(len));
    if let Ok(style) = ProgressStyle::with_template(template) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_prefix(prefix.to_string());
    Some(bar)
}

/// Take the command's bar off the screen.
pub fn finish_bar(bar: Option<ProgressBar>) {
    if let Some(bar) = bar {
        take_off(bar);
    }
}

/// Take `bar` off the screen and out of [`BARS`].
fn take_off(bar: ProgressBar) {
    bar.finish_and_clear();
    BARS.remove(&bar);
}

/// Catch Ctrl-C (and SIGTERM, SIGHUP) for the rest of the process: each is counted, the
/// [`HARD_EXIT`]-th ends the process with exit code 130. If the handler cannot be installed,
/// they end the process as by default, which a warning says.
pub fn catch_interrupts() {
    let handler = || {
        let n = INTERRUPTS.fetch_add(1, Ordering::SeqCst) + 1;
        if n >= HARD_EXIT {
            std::process::exit(130);
        }
    };
    if let Err(e) = ctrlc::set_handler(handler) {
        tracing::warn!("cannot catch Ctrl-C ({e}): it will end the process at once");
    }
}

/// Interrupts received so far.
pub fn interrupts() -> u32 {
    INTERRUPTS.load(Ordering::SeqCst)
}

/// Let runs show progress bars when stderr is a terminal, unless `quiet`.
pub fn enable_progress(quiet: bool) {
    PROGRESS.store(!quiet && std::io::stderr().is_terminal(), Ordering::Relaxed);
}

/// Run `f` (a write to stderr) with the progress bars, if any are shown, out of its way.
pub fn suspend<R>(f: impl FnOnce() -> R) -> R {
    if PROGRESS.load(Ordering::Relaxed) {
        BARS.suspend(f)
    } else {
        f()
    }
}

/// A host-time limit as given (`10min`, `90s`, `1.5h`, or `none`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HostLimit {
    pub limit: Option<Duration>,
    pub text: String,
}

/// Parse `--host-time-limit`: a number (decimals allowed) and a unit of ms, s, min or h; or
/// `none`, no limit. Zero is refused: it would stop every run before it starts.
pub fn parse_host_limit(text: &str) -> Result<HostLimit, String> {
    let t = text.trim();
    if t == "none" {
        return Ok(HostLimit {
            limit: None,
            text: t.to_string(),
        });
    }
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let value: f64 = number
        .parse()
        .map_err(|_| format!("`{t}` is not a number and a unit (e.g. 10min, 90s, 1.5h)"))?;
    let scale = match unit {
        "ms" => 1e-3,
        "s" => 1.0,
        "min" => 60.0,
        "h" => 3600.0,
        "" => {
            return Err(format!(
                "`{t}` has no unit: give ms, s, min or h (e.g. 10min)"
            ));
        }
        _ => {
            return Err(format!(
                "`{unit}` is no unit of host time: give ms, s, min or h"
            ));
        }
    };
    let seconds = value * scale;
    // A year: longer is no limit at all, and Duration would overflow far beyond.
    const MAX_SECONDS: f64 = 365.0 * 24.0 * 3600.0;
    if !(seconds > 0.0 && seconds <= MAX_SECONDS) {
        return Err(format!(
            "`{t}` must be more than 0 and at most a year (or `none` for no limit)"
        ));
    }
    Ok(HostLimit {
        limit: Some(Duration::from_secs_f64(seconds)),
        text: t.to_string(),
    })
}

/// Parse `--time-limit`, simulated time (`10s`, `500ms`, `2.5us`: the units of
/// `pxpl5_trace::parse_time`).
pub fn parse_time_limit(text: &str) -> Result<Tick, String> {
    pxpl5_trace::parse_time(text).map_err(|e| e.to_string())
}

/// Simulated seconds as a reader wants them: in s, ms, us or ns, with 3 decimals.
pub fn seconds(s: f64) -> String {
    let a = s.abs();
    if a >= 1.0 || a == 0.0 {
        format!("{s:.3} s")
    } else if a >= 1e-3 {
        format!("{:.3} ms", s * 1e3)
    } else if a >= 1e-6 {
        format!("{:.3} us", s * 1e6)
    } else {
        format!("{:.3} ns", s * 1e9)
    }
}

/// A work estimate is large past these (about a minute of host time or more, measured on the
/// main job's host, where the default radiosity run takes about 3 s).
pub mod large {
    /// GPs + Renderers: the machine's loop visits every unit at each instant, so runs slow down
    /// about with the square of the units (the default radiosity job: 3 s with 20 units, 9 s
    /// with 204, over a minute with 1,004).
    pub const UNITS: u64 = 256;
    /// Radiosity receiver draws (patches x shots x methods x Renderer tiles per view), as the
    /// shot cap allows them (a run that reaches its accuracy target stops well before): the
    /// default job (199 patches, at most 1,990 shots, 2 methods: 792,020 at most) draws about
    /// 250,000 in 13 s of host time, some 50 us each, so 5,000,000 would take about 4 minutes.
    pub const RECEIVER_DRAWS: u64 = 5_000_000;
    /// Triangles of `pxpl5 run` (402 take 0.1 s, 20,000 take 2.5 s).
    pub const TRIANGLES: u64 = 500_000;
}

/// What a run will do, estimated from its inputs before it starts.
pub struct Estimate<'a> {
    /// What runs, as messages name it.
    pub name: &'a str,
    /// GPs + Renderers.
    pub units: u64,
    /// The program's work, what it counts, and the count past which it is large.
    pub work: u64,
    pub work_is: &'a str,
    pub large: u64,
}

/// Log `e` at info level, and warn when the run is large: it will take minutes, and the
/// host-time limit may stop it.
pub fn estimate(e: &Estimate, host: &HostLimit) {
    tracing::info!(
        run = %e.name,
        units = e.units,
        work = e.work,
        "work estimate: {} {}", e.work, e.work_is
    );
    let mut large = Vec::new();
    if e.units > large::UNITS {
        large.push(format!(
            "{} GPs and Renderers, more than {} (the machine visits every unit at each instant, \
             so time grows about with their square)",
            thousands(e.units),
            large::UNITS
        ));
    }
    if e.work > e.large {
        large.push(format!(
            "{} {}, more than {}",
            thousands(e.work),
            e.work_is,
            thousands(e.large)
        ));
    }
    if !large.is_empty() {
        tracing::warn!(
            "{}: a large run: {}; it may take many minutes (--host-time-limit {} stops it)",
            e.name,
            large.join("; "),
            host.text
        );
    }
}

/// `n` with its thousands separated by commas, as the messages write counts.
fn thousands(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (k, c) in digits.chars().enumerate() {
        if k > 0 && (digits.len() - k).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// One simulation as the watch reports on it.
pub struct Sim<'a> {
    /// What runs, as messages name it: `run`, `radiosity (hemisphere)`, ...
    pub name: &'a str,
    /// Shots asked, when the program counts its shots in the monitor (radiosity).
    pub shots: Option<u64>,
    /// What the first Ctrl-C asks of this run: `Stop::Soon` (the radiosity program ends between
    /// shots; a program without such a point runs on to its end) or `Stop::Now`.
    pub interrupt: Stop,
}

/// Why the watcher asked a run to stop at once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Why {
    Interrupt,
    HostLimit,
}

/// The watch of one command: its host-time limit, counted from the command's start.
pub struct Watch {
    started: Instant,
    host: HostLimit,
}

impl Watch {
    /// A watch whose host-time limit `host` starts now.
    pub fn new(host: HostLimit) -> Watch {
        Watch {
            started: Instant::now(),
            host,
        }
    }

    pub fn host_limit(&self) -> &HostLimit {
        &self.host
    }

    /// Run `run`, one simulation (a library call that builds and runs a machine with the
    /// options it is given: `options` with a fresh monitor), under watch, and return its result
    /// with the host seconds it took. Logs the start and the end (simulated time, `end` of the
    /// result; host seconds) at info level. A failure is classified: a stop asked by the watcher
    /// is an interrupt or the host-time limit, a machine config the machine cannot build a
    /// user's mistake, anything else a failed simulation; each message says where it was.
    pub fn simulate<T>(
        &self,
        sim: &Sim,
        mut options: RunOptions,
        run: impl FnOnce(RunOptions) -> Result<T, RunError>,
        end: impl FnOnce(&T) -> Tick,
    ) -> Result<(T, f64), Failure> {
        tracing::info!(run = %sim.name, fidelity = %options.fidelity.name(), "simulation starts");
        let monitor = Arc::new(Monitor::default());
        // An interrupt that came before the run applies from its start.
        monitor.request(stop_for(interrupts(), sim.interrupt));
        options.monitor = Some(monitor.clone());
        let deadline = self.host.limit.map(|l| self.started + l);
        let t0 = Instant::now();
        let (result, why) = std::thread::scope(|scope| {
            let (done, ended) = mpsc::channel::<()>();
            let watcher = scope.spawn(|| watcher(ended, &monitor, sim, deadline, t0));
            let result = run(options);
            drop(done);
            // The watcher only reads atomics and draws: it cannot panic but in indicatif.
            (result, watcher.join().ok().flatten())
        });
        let host_seconds = t0.elapsed().as_secs_f64();
        match result {
            Ok(r) => {
                tracing::info!(
                    run = %sim.name,
                    simulated_ms = %format!("{:.6}", end(&r).as_secs_f64() * 1e3),
                    host_s = %format!("{host_seconds:.3}"),
                    "simulation ends"
                );
                Ok((r, host_seconds))
            }
            Err(e) => Err(self.failure(sim, e, why, &monitor)),
        }
    }

    /// The failure `e` of `sim`'s run, stopped for `why` if the watcher stopped it: what
    /// happened, where the run was (simulated time, shots done), and the units still running, a
    /// line each.
    fn failure(&self, sim: &Sim, e: RunError, why: Option<Why>, monitor: &Monitor) -> Failure {
        let name = sim.name;
        let shots = sim
            .shots
            .map(|n| format!(", {} of {n} shots done", monitor.done()))
            .unwrap_or_default();
        let at = |t: Tick| format!("at {} of simulated time{shots}", seconds(t.as_secs_f64()));
        match e {
            RunError::Stopped { at: t, running } => {
                let at = at(t);
                let units = units_list(&running);
                if why == Some(Why::HostLimit) {
                    Failure::SimulationFailed(format!(
                        "{name}: host time limit of {} reached (--host-time-limit): stopped {at}; \
                         nothing written. Still running:{units}",
                        self.host.text
                    ))
                } else {
                    Failure::Interrupted(format!(
                        "{name}: interrupted {at}; nothing written. Still running:{units}"
                    ))
                }
            }
            RunError::TimeLimit { limit, running } => Failure::SimulationFailed(format!(
                "{name}: simulated time limit of {} reached (--time-limit){shots}; nothing \
                 written. Still running:{}",
                seconds(limit.as_secs_f64()),
                units_list(&running)
            )),
            // The config validator should have refused it: the user's config all the same.
            RunError::Config(_) => Failure::UserMistake(format!("{name}: {e}")),
            // A deadlock says when and who waits; a program's error where.
            _ => Failure::SimulationFailed(format!(
                "{name}: {e}\n({}nothing written)",
                sim.shots
                    .map(|n| format!("{} of {n} shots done; ", monitor.done()))
                    .unwrap_or_default()
            )),
        }
    }
}

/// The machine's list of units still running (`UNIT N: what`, joined with `; `), a line each,
/// consecutive units of one kind in one state on one line (`GP 0-15: computing`): a machine of
/// a thousand GPs gives a report one can read.
fn units_list(running: &str) -> String {
    // (kind, first, last, what) of each group so far.
    let mut groups: Vec<(String, u64, u64, String)> = Vec::new();
    let mut out = String::new();
    for line in running.split("; ").map(str::trim) {
        let parsed = line.split_once(": ").and_then(|(unit, what)| {
            let (kind, n) = unit.rsplit_once(' ')?;
            Some((kind.to_string(), n.parse::<u64>().ok()?, what.to_string()))
        });
        match (parsed, groups.last_mut()) {
            (Some((kind, n, what)), Some(g)) if g.0 == kind && g.3 == what && g.2 + 1 == n => {
                g.2 = n;
            }
            (Some((kind, n, what)), _) => groups.push((kind, n, n, what)),
            (None, _) => out += &format!("\n  {line}"),
        }
    }
    let mut listed: String = groups
        .into_iter()
        .map(|(kind, first, last, what)| match first == last {
            true => format!("\n  {kind} {first}: {what}"),
            false => format!("\n  {kind} {first}-{last}: {what}"),
        })
        .collect();
    listed += &out;
    listed
}

/// What `n` interrupts ask of a run whose first asks `first`.
fn stop_for(n: u32, first: Stop) -> Stop {
    match n {
        0 => Stop::None,
        1 => first,
        _ => Stop::Now,
    }
}

/// The watcher of one run, until `ended` disconnects: passes interrupts and the host deadline
/// on to `monitor`, logs shots done, draws the progress bar. Returns why it asked a stop now.
fn watcher(
    ended: mpsc::Receiver<()>,
    monitor: &Monitor,
    sim: &Sim,
    deadline: Option<Instant>,
    t0: Instant,
) -> Option<Why> {
    let mut why = None;
    let mut bar: Option<ProgressBar> = None;
    let mut shots_logged = 0;
    loop {
        let mut wait = POLL;
        if let (None, Some(d)) = (why, deadline) {
            wait = wait.min(d.saturating_duration_since(Instant::now()));
        }
        match ended.recv_timeout(wait) {
            Err(RecvTimeoutError::Timeout) => {}
            Ok(()) | Err(RecvTimeoutError::Disconnected) => break,
        }
        if why.is_none() {
            let stop = stop_for(interrupts(), sim.interrupt);
            monitor.request(stop);
            if stop == Stop::Now {
                why = Some(Why::Interrupt);
            } else if deadline.is_some_and(|d| Instant::now() >= d) {
                monitor.request(Stop::Now);
                why = Some(Why::HostLimit);
            }
        }
        let done = monitor.done();
        if sim.shots.is_some() && done > shots_logged {
            shots_logged = done;
            tracing::info!(
                run = %sim.name,
                simulated_ms = %format!("{:.6}", monitor.reached().as_secs_f64() * 1e3),
                "{done} of {} shots done",
                sim.shots.unwrap_or(0)
            );
        }
        let host = t0.elapsed();
        if bar.is_none()
            && host >= SHOW_AFTER
            && PROGRESS.load(Ordering::Relaxed)
            && RUN_BARS.load(Ordering::Relaxed)
        {
            bar = Some(show_bar(sim));
        }
        if let Some(bar) = &bar {
            bar.set_position(done);
            bar.set_message(progress_message(monitor.reached(), host));
        }
    }
    if let Some(bar) = bar {
        take_off(bar);
    }
    why
}

/// A progress bar for `sim` on stderr, among [`BARS`].
fn show_bar(sim: &Sim) -> ProgressBar {
    let (bar, template) = match sim.shots {
        Some(n) => (
            ProgressBar::new(n),
            "{prefix}: {pos}/{len} shots [{bar:20}] {wide_msg}",
        ),
        None => (ProgressBar::no_length(), "{prefix}: {spinner} {wide_msg}"),
    };
    if let Ok(style) = ProgressStyle::with_template(template) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_prefix(sim.name.to_string());
    BARS.add(bar)
}

/// The bar's message: simulated time reached, simulated time per host second, host time (cut
/// at the terminal's width).
fn progress_message(reached: Tick, host: Duration) -> String {
    let simulated = reached.as_secs_f64();
    let rate = simulated / host.as_secs_f64().max(1e-9);
    format!(
        "{} simulated, {}/host s, host {:.0} s",
        seconds(simulated),
        seconds(rate),
        host.as_secs_f64()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn host_limits_parse_with_units_or_none() {
        let ok = |t: &str| parse_host_limit(t).map(|h| h.limit);
        assert_eq!(ok("10min"), Ok(Some(Duration::from_secs(600))));
        assert_eq!(ok("90s"), Ok(Some(Duration::from_secs(90))));
        assert_eq!(ok("1.5h"), Ok(Some(Duration::from_secs(5400))));
        assert_eq!(ok("250ms"), Ok(Some(Duration::from_millis(250))));
        assert_eq!(ok("none"), Ok(None));
        for bad in [
            "0s", "10", "10m", "ten min", "-1s", "1e9h", "", "s", "..s", "nan s",
        ] {
            assert!(parse_host_limit(bad).is_err(), "{bad}");
        }
        assert_eq!(
            parse_host_limit(DEFAULT_HOST_LIMIT).map(|h| h.limit),
            Ok(Some(Duration::from_secs(600)))
        );
    }

    /// Each machine error gets its class, and its message where the run was.
    #[test]
    fn run_errors_are_classified() {
        let watch = Watch::new(parse_host_limit("90s").expect("parses"));
        let sim = Sim {
            name: "radiosity (hemicube)",
            shots: Some(6),
            interrupt: Stop::Soon,
        };
        let monitor = Monitor::default();
        monitor.set_done(2);
        let running = "  GP 0: waits for a message;   GP 1: waits for a message".to_string();
        let deadlock = RunError::Deadlock {
            at: Tick(2_500_000),
            waiting: running.clone(),
        };
        let failure = watch.failure(&sim, deadlock, None, &monitor);
        assert_eq!(failure.exit_code(), 1);
        assert!(
            failure.message().starts_with(
                "radiosity (hemicube): deadlock at 2500000 ps: every unit waits and nothing is due"
            ) && failure
                .message()
                .ends_with("(2 of 6 shots done; nothing written)"),
            "{}",
            failure.message()
        );
        let stopped = || RunError::Stopped {
            at: Tick(1_500_000_000),
            running: running.clone(),
        };
        let host = watch.failure(&sim, stopped(), Some(Why::HostLimit), &monitor);
        assert_eq!(
            host,
            Failure::SimulationFailed(
                "radiosity (hemicube): host time limit of 90s reached (--host-time-limit): \
                 stopped at 1.500 ms of simulated time, 2 of 6 shots done; nothing written. \
                 Still running:\n  GP 0-1: waits for a message"
                    .into()
            )
        );
        let interrupted = watch.failure(&sim, stopped(), Some(Why::Interrupt), &monitor);
        assert_eq!(interrupted.exit_code(), 130);
        assert!(interrupted.message().contains("interrupted at 1.500 ms"));
        let config = watch.failure(&sim, RunError::Config("x".into()), None, &monitor);
        assert_eq!(config.exit_code(), 2);
        let program = RunError::Program {
            gp: 3,
            message: "boom".into(),
        };
        assert_eq!(watch.failure(&sim, program, None, &monitor).exit_code(), 1);
    }

    #[test]
    fn units_in_one_state_share_a_line() {
        let running = "  GP 0: computing;   GP 1: computing;   GP 2: waits for a message;   \
                       GP 3: computing;   GP 4: computing;   Renderer 0: 3 commands queued;   \
                       Renderer 1: 3 commands queued";
        assert_eq!(
            units_list(running),
            "\n  GP 0-1: computing\n  GP 2: waits for a message\n  GP 3-4: computing\n  \
             Renderer 0-1: 3 commands queued"
        );
        assert_eq!(
            units_list("  (no unit is waiting)"),
            "\n  (no unit is waiting)"
        );
    }

    #[test]
    fn counts_have_thousands_separators() {
        let shown: Vec<String> = [0, 999, 1000, 250_000, 42_300_000, u64::MAX]
            .into_iter()
            .map(thousands)
            .collect();
        assert_eq!(
            shown,
            [
                "0",
                "999",
                "1,000",
                "250,000",
                "42,300,000",
                "18,446,744,073,709,551,615"
            ]
        );
    }

    #[test]
    fn interrupts_escalate() {
        assert_eq!(stop_for(0, Stop::Soon), Stop::None);
        assert_eq!(stop_for(1, Stop::Soon), Stop::Soon);
        assert_eq!(stop_for(1, Stop::Now), Stop::Now);
        assert_eq!(stop_for(2, Stop::Soon), Stop::Now);
    }

    #[test]
    fn seconds_read_in_the_right_unit() {
        assert_eq!(seconds(0.0), "0.000 s");
        assert_eq!(seconds(2.5), "2.500 s");
        assert_eq!(seconds(0.034128), "34.128 ms");
        assert_eq!(seconds(2.5e-6), "2.500 us");
        assert_eq!(seconds(4e-9), "4.000 ns");
        assert_eq!(
            progress_message(Tick(34_128_000_000), Duration::from_secs(2)),
            "34.128 ms simulated, 17.064 ms/host s, host 2 s"
        );
    }
}
