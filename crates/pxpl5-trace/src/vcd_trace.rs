//! [`VcdTrace`]: a builder of Value Change Dump files (for GTKWave, Surfer) over simulated time,
//! written through the `vcd` crate.
//!
//! # Output format
//!
//! * `$timescale 1 ps $end`: VCD times are [`Tick`]s unchanged, absolute simulated time (also
//!   inside a window, so they match the simulator's other reports).
//! * No `$date` and no version number: a file must depend only on the run, so identical runs give
//!   identical bytes. A `$comment` says the times are simulated, and names the window if any.
//! * One `$scope module` per scope, in creation order, holding its wires in creation order. Wires
//!   wider than one bit carry the range `[W-1:0]`. Identifier codes are the `vcd` crate's
//!   [`IdCode`]s numbered in wire creation order.
//! * Initial values: every wire starts at 0 (not `x`: the simulator's state is defined from time
//!   zero, so "unknown" would be a lie). They are written under `$dumpvars` at the window start
//!   (`#0` for the whole run), after folding in every change at or before that instant.
//! * Changes may be recorded in any order. They are written sorted by time, then wire creation
//!   order. When one wire changes several times at one instant, the last recorded value wins (as
//!   in a simulator's delta cycles); a change to the value a wire already has is not written.
//! * Window: changes before the start are folded into the initial values, changes at or after
//!   the end are dropped (both as they are recorded, so a long run need not fit in memory).
//! * Names: a VCD name may hold no whitespace, so characters other than printable ASCII (space
//!   included) become `_`, and an empty name becomes `_`.
//!
//! # Streaming
//!
//! [`VcdTrace::new`] holds every change until [`VcdTrace::write`]. [`VcdTrace::streamed`]
//! writes the same bytes as the run goes, to a writer given at creation, with memory bounded by
//! the changes recorded between two writes ([`VcdTrace::FLUSH_AT`]) instead of by the run's length. Its
//! recorder promises, by [`VcdTrace::settle`]`(now)`, that no change before `now` will be
//! recorded from then on (a simulator records a change when it decides it, at its current
//! instant or later); a change recorded before a settled instant is a bug of the recorder, and
//! [`VcdTrace::finish`] returns it as an error instead of writing the file out of order. The header is written once time
//! has settled past the window's start (the initial values need every change up to it), so
//! every wire and comment must be declared before that. [`VcdTrace::finish`] writes the rest
//! and returns the first write error.

use std::collections::HashMap;
use std::fmt;
use std::io::{self, Write};

use pxpl5_sim::Tick;
use vcd::{IdCode, ReferenceIndex, SimulationCommand, TimescaleUnit, VarType};

use crate::window::TraceWindow;

/// Widest wire a `u64` value can drive.
pub const MAX_WIDTH: u32 = 64;

/// A scope (VCD module) of one [`VcdTrace`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ScopeId(usize);

/// A wire of one [`VcdTrace`]; meaningless to any other trace.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SignalId(usize);

/// A text as a value of string variables ([`VcdTrace::text_value`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextValue(u64);

/// A wire asked for with a width no `u64` value can drive: 0, or above [`MAX_WIDTH`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WidthError {
    /// The wire's name.
    pub name: String,
    /// The width asked for.
    pub width: u32,
}

impl fmt::Display for WidthError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "VCD wire `{}` has width {}; expected 1 to {MAX_WIDTH} bits",
            self.name, self.width
        )
    }
}

impl std::error::Error for WidthError {}

#[derive(Debug)]
struct Scope {
    name: String,
    signals: Vec<usize>,
}

#[derive(Debug)]
struct Signal {
    name: String,
    /// Bits of a wire; 0 for a string variable, whose values index [`VcdTrace::texts`].
    width: u32,
    /// The value at the window start and when it was set (for folding changes recorded out of
    /// order: the latest one wins).
    initial: Option<(Tick, u64)>,
    /// A streamed trace's wire set by spans ([`VcdTrace::span`]): the end of its latest span,
    /// not recorded yet.
    held_end: Option<Tick>,
}

/// A change inside the window, after its start: when, which wire (its index), the value.
type Change = (Tick, usize, u64);

/// Where a streamed trace writes, and what it has written so far (see "Streaming" in the
/// module docs).
struct Stream {
    out: vcd::Writer<Box<dyn Write + Send>>,
    /// What the body has written: set once the header and `$dumpvars` are out.
    body: Option<Body>,
    /// No change before this instant will be recorded ([`VcdTrace::settle`]).
    settled: Tick,
    /// The first write error; nothing is written after it.
    error: Option<io::Error>,
}

impl Stream {
    /// Whether [`VcdTrace::finish`] has run: it settles time at its end, `Tick(u64::MAX)`.
    fn finished(&self) -> bool {
        self.settled == Tick(u64::MAX)
    }
}

impl fmt::Debug for Stream {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Stream")
            .field("started", &self.body.is_some())
            .field("settled", &self.settled)
            .field("error", &self.error)
            .finish_non_exhaustive()
    }
}

/// The state of a VCD body being written: each wire's value as written, and the last timestamp.
#[derive(Debug)]
struct Body {
    current: Vec<u64>,
    last_time: Tick,
    /// What ends each wire's value line: its identifier code as the vcd crate writes it, and
    /// the newline; made once.
    tails: Vec<Box<[u8]>>,
    /// Per wire, by value, its whole value lines, each made the first time it is written: a
    /// 1-bit wire's two, and the texts a string variable takes (a ring token's position takes
    /// a few, at most instants). Wider wires keep none.
    lines: Vec<Vec<Line>>,
    /// The text of the changes being written, sent to the writer in one piece per batch.
    text: Vec<u8>,
}

/// A value line kept by [`Body::lines`], padded to a fixed length so that appending it is a copy
/// of known length and a truncation (a copy of a few bytes of unknown length is a call to
/// `memcpy`, most of the cost of a line).
#[derive(Clone, Copy, Debug)]
struct Line {
    bytes: [u8; Line::MAX],
    /// 0 for a line not made yet.
    len: u8,
}

impl Line {
    /// The longest line kept; a longer one is made each time it is written.
    const MAX: usize = 32;
    const NONE: Line = Line {
        bytes: [0; Line::MAX],
        len: 0,
    };

    fn new(text: &[u8]) -> Option<Line> {
        let mut line = Line::NONE;
        line.bytes.get_mut(..text.len())?.copy_from_slice(text);
        line.len = text.len() as u8;
        Some(line)
    }
}

/// A builder of a VCD file over simulated time. See the module docs for the output format.
#[derive(Debug)]
pub struct VcdTrace {
    window: TraceWindow,
    scopes: Vec<Scope>,
    scope_ids: HashMap<String, ScopeId>,
    signals: Vec<Signal>,
    end: Option<Tick>,
    /// Comments written in the header, in order (e.g. a legend of the values of a wire).
    comments: Vec<String>,
    /// The values string variables take, interned: a change stores the index.
    texts: Vec<String>,
    text_ids: HashMap<String, u64>,
    /// Changes inside the window, after its start, in recording order; when streamed, only
    /// those not yet written, and not those at the settled instant (`at_settled`).
    changes: Vec<Change>,
    /// A streamed trace's changes at the instant settled when they were recorded, not yet
    /// written: sorted by time and wire, one per (time, wire), the last recorded. They need no
    /// sort: a recorder samples its wires at the settled instant (a ring token's position at
    /// every instant), in turn. A change held in `changes` at the same time and wire was
    /// recorded before (time had not settled there yet), so one here wins.
    at_settled: Vec<Change>,
    /// The other buffer of [`sort_changes`] (host work only).
    scratch: Vec<Change>,
    /// Set for a trace written as it is recorded ([`VcdTrace::streamed`]).
    stream: Option<Stream>,
}

impl Default for VcdTrace {
    fn default() -> VcdTrace {
        VcdTrace::new(TraceWindow::all())
    }
}

impl VcdTrace {
    /// A streamed trace writes what has settled once it holds this many changes: with the
    /// changes recorded ahead of the settled instant, the bound on its memory beyond the wires
    /// (24 bytes a change, 1.5 MiB).
    pub const FLUSH_AT: usize = 1 << 16;

    /// An empty trace keeping what falls in `window`.
    pub fn new(window: TraceWindow) -> VcdTrace {
        VcdTrace {
            window,
            scopes: Vec::new(),
            scope_ids: HashMap::new(),
            signals: Vec::new(),
            end: None,
            comments: Vec::new(),
            texts: Vec::new(),
            text_ids: HashMap::new(),
            changes: Vec::new(),
            at_settled: Vec::new(),
            scratch: Vec::new(),
            stream: None,
        }
    }

    /// An empty trace keeping what falls in `window`, written to `out` as it is recorded (see
    /// "Streaming" in the module docs): its recorder calls [`VcdTrace::settle`] as time goes
    /// on and [`VcdTrace::finish`] at the end, and never [`VcdTrace::write`].
    pub fn streamed(window: TraceWindow, out: Box<dyn Write + Send>) -> VcdTrace {
        VcdTrace {
            stream: Some(Stream {
                out: vcd::Writer::new(out),
                body: None,
                settled: Tick::ZERO,
                error: None,
            }),
            ..VcdTrace::new(window)
        }
    }

    /// The window this trace keeps.
    pub fn window(&self) -> TraceWindow {
        self.window
    }

    /// Whether the trace is written as it is recorded ([`VcdTrace::streamed`]).
    pub fn is_streamed(&self) -> bool {
        self.stream.is_some()
    }

    /// The changes held in memory, not yet written.
    pub fn held_changes(&self) -> usize {
        self.changes.len() + self.at_settled.len()
    }

    /// The scope (VCD module) named `name`, created on first use.
    pub fn scope(&mut self, name: &str) -> ScopeId {
        if let Some(&id) = self.scope_ids.get(name) {
            return id;
        }
        let id = ScopeId(self.scopes.len());
        self.scopes.push(Scope {
            name: name.to_owned(),
            signals: Vec::new(),
        });
        self.scope_ids.insert(name.to_owned(), id);
        id
    }

    /// A new wire `name` of `width` bits in `scope`, initially 0.
    ///
    /// # Panics
    ///
    /// If `width` is 0 or above [`MAX_WIDTH`]: widths come from the simulator's code, never from
    /// its user, so a bad one is a bug to stop at ([`VcdTrace::try_wire`] reports it instead).
    pub fn wire(&mut self, scope: ScopeId, name: &str, width: u32) -> SignalId {
        self.try_wire(scope, name, width)
            .unwrap_or_else(|e| panic!("{e}"))
    }

    /// [`VcdTrace::wire`], returning a width of 0 or above [`MAX_WIDTH`] as an error instead of
    /// panicking (the trace is unchanged then).
    pub fn try_wire(
        &mut self,
        scope: ScopeId,
        name: &str,
        width: u32,
    ) -> Result<SignalId, WidthError> {
        if !(1..=MAX_WIDTH).contains(&width) {
            return Err(WidthError {
                name: name.to_owned(),
                width,
            });
        }
        self.assert_header_open(name);
        let id = SignalId(self.signals.len());
        self.signals.push(Signal {
            name: name.to_owned(),
            width,
            initial: None,
            held_end: None,
        });
        self.scopes[scope.0].signals.push(id.0);
        Ok(id)
    }

    /// A new string variable `name` in `scope` (`$var string`, which GTKWave and Surfer show as
    /// text), initially `initial`; set it with [`VcdTrace::change_text`]. Its values are written
    /// as VCD names are: printable ASCII, anything else `_`.
    pub fn text(&mut self, scope: ScopeId, name: &str, initial: &str) -> SignalId {
        self.assert_header_open(name);
        let id = SignalId(self.signals.len());
        let initial = self.text_id(initial);
        self.signals.push(Signal {
            name: name.to_owned(),
            width: 0,
            initial: Some((Tick::ZERO, initial)),
            held_end: None,
        });
        self.scopes[scope.0].signals.push(id.0);
        id
    }

    /// Records that string variable `signal` (from [`VcdTrace::text`]) reads `value` from `at`.
    pub fn change_text(&mut self, signal: SignalId, at: Tick, value: &str) {
        let value = self.text_value(value);
        self.change_to(signal, at, value);
    }

    /// `text` as a value of string variables, for [`VcdTrace::change_to`]: a caller that sets
    /// the same few texts often names each once, instead of having it looked up at every change.
    pub fn text_value(&mut self, text: &str) -> TextValue {
        TextValue(self.text_id(text))
    }

    /// [`VcdTrace::change_text`] with a text named by [`VcdTrace::text_value`].
    pub fn change_to(&mut self, signal: SignalId, at: Tick, value: TextValue) {
        self.change(signal, at, value.0);
    }

    /// Adds a `$comment` to the header (after the builder's own), e.g. what a wire's numbers mean.
    pub fn comment(&mut self, text: &str) {
        self.assert_header_open("a comment");
        self.comments.push(text.to_owned());
    }

    /// A streamed trace writes its header once time has settled past the window's start; a wire
    /// or comment declared after that would be missing from it, a bug of the recorder.
    fn assert_header_open(&self, what: &str) {
        assert!(
            self.stream.as_ref().is_none_or(|s| s.body.is_none()),
            "VCD: {what} declared after the streamed header was written"
        );
    }

    fn text_id(&mut self, text: &str) -> u64 {
        let text = vcd_name(text);
        if let Some(&id) = self.text_ids.get(&text) {
            return id;
        }
        let id = self.texts.len() as u64;
        self.texts.push(text.clone());
        self.text_ids.insert(text, id);
        id
    }

    /// Records that `signal` takes `value` at `at`. Bits above the wire's width are dropped, as
    /// when a Verilog value is assigned to a narrower wire.
    #[inline(always)]
    pub fn change(&mut self, signal: SignalId, at: Tick, value: u64) {
        let window = self.window;
        if at >= window.end {
            return;
        }
        let mut at_settled = false;
        if let Some(stream) = &mut self.stream {
            if at < stream.settled {
                // Written already up to `settled`: the change would come out of order. The
                // recorder broke its promise (a simulator bug); the trace fails rather than lie.
                if stream.error.is_none() {
                    stream.error = Some(io::Error::new(
                        io::ErrorKind::InvalidData,
                        format!(
                            "VCD change at {at} recorded after time settled at {} (a simulator bug)",
                            stream.settled
                        ),
                    ));
                }
                return;
            }
            at_settled = at == stream.settled;
        }
        self.hold(signal, at, value, at_settled);
    }

    /// Changes at one instant `at`, recorded through the returned [`Sample`] as
    /// [`VcdTrace::change`] would record each: for a recorder that samples many wires at every
    /// instant (a ring token's position), the window and the settled instant are looked at once
    /// per instant instead of once per change.
    pub fn sample(&mut self, at: Tick) -> Sample<'_> {
        let settled = self.stream.as_ref().is_some_and(|s| s.settled == at)
            && self.window.start < at
            && at < self.window.end;
        Sample {
            at,
            settled,
            trace: self,
        }
    }

    /// Holds a change inside the window (see [`VcdTrace::change`]): folded into the initial
    /// value, kept as one at the settled instant, or kept to be sorted.
    #[inline(always)]
    fn hold(&mut self, signal: SignalId, at: Tick, value: u64, at_settled: bool) {
        let window = self.window;
        if at >= window.end {
            return;
        }
        let s = &mut self.signals[signal.0];
        let value = mask(value, s.width);
        if at <= window.start {
            // Later changes win; at equal times the later-recorded one does, as in `write`.
            if s.initial.is_none_or(|(t, _)| at >= t) {
                s.initial = Some((at, value));
            }
        } else if at_settled {
            hold_settled(&mut self.at_settled, (at, signal.0, value));
        } else {
            self.changes.push((at, signal.0, value));
        }
    }

    /// Records that 1-bit wire `signal` is 1 over `[start, end)`, as [`VcdTrace::change`] to 1
    /// at `start` and to 0 at `end` does, for a wire set by spans alone, each starting no
    /// earlier than the previous one ends (a unit's busy spans: it does one thing at a time).
    ///
    /// A streamed trace joins spans that follow one another at once: the end of the latest is
    /// held back until the next span starts, or a write reaches it. A span that starts where
    /// the previous one ended would set the wire to 0 and back to 1 at one instant, which the
    /// file does not show; a Renderer's commands and a GP's busy spans mostly follow at once,
    /// and the pairs were most of the changes of a machine's VCD, whose cost is per change.
    pub fn span(&mut self, signal: SignalId, start: Tick, end: Tick) {
        let Some(stream) = &self.stream else {
            self.change(signal, start, 1);
            self.change(signal, end, 0);
            return;
        };
        let settled = stream.settled;
        debug_assert!(
            end >= start
                && self.signals[signal.0]
                    .held_end
                    .is_none_or(|last| start >= last),
            "VCD spans of one wire overlap or run backwards: a bug of the recorder"
        );
        match self.signals[signal.0].held_end.take() {
            Some(last) if last == start => {}
            Some(last) => {
                // Held since before time settled there: recorded then, not at the settled
                // instant (a write moves the ends it reaches first, so none is written past).
                self.hold(signal, last, 0, false);
                self.change(signal, start, 1);
            }
            None => self.change(signal, start, 1),
        }
        if end == settled {
            // No span can start later at the settled instant and be joined: a change there
            // now, after the start's (in the list of the settled instant, whose last wins).
            self.change(signal, end, 0);
        } else {
            self.signals[signal.0].held_end = Some(end);
        }
    }

    /// For a streamed trace: no change before `now` will be recorded from here on, so what lies
    /// before it may be written (it is, in batches of [`VcdTrace::FLUSH_AT`] changes). `now` never moves
    /// back. A trace not streamed ignores it.
    pub fn settle(&mut self, now: Tick) {
        let Some(stream) = &mut self.stream else {
            return;
        };
        stream.settled = stream.settled.max(now);
        let settled = stream.settled;
        if self.held_changes() >= Self::FLUSH_AT {
            self.flush(settled);
        }
    }

    /// Ends a streamed trace: writes every change held and the end's timestamp, and flushes the
    /// writer. Returns the first write error, if any. A trace not streamed writes nothing.
    pub fn finish(&mut self) -> io::Result<()> {
        if self.stream.as_ref().is_none_or(Stream::finished) {
            return Ok(());
        }
        self.flush(Tick(u64::MAX));
        let Some(mut stream) = self.stream.take() else {
            return Ok(());
        };
        let ended = match (stream.error.take(), &stream.body) {
            (Some(e), _) => Err(e),
            (None, Some(body)) => self.end_body(&mut stream.out, body),
            (None, None) => Ok(()),
        };
        stream.settled = Tick(u64::MAX);
        self.stream = Some(stream);
        ended
    }

    /// Writes the header (first time) and the held changes before `before`, keeping the rest.
    fn flush(&mut self, before: Tick) {
        let Some(mut stream) = self.stream.take() else {
            return;
        };
        // The header's initial values need every change at or before the window's start (the
        // end of time, at `finish`, writes the header even of a window starting there).
        if before > self.window.start || before == Tick(u64::MAX) {
            // The spans' ends held back that this write reaches: no span can start at them any
            // more (time settled past them), so each is the wire's last change there.
            for index in 0..self.signals.len() {
                if let Some(end) = self.signals[index].held_end
                    && (end < before || before == Tick(u64::MAX))
                {
                    self.signals[index].held_end = None;
                    self.hold(SignalId(index), end, 0, false);
                }
            }
            if stream.error.is_none() && stream.body.is_none() {
                match self.begin_body(&mut stream.out) {
                    Ok(body) => stream.body = Some(body),
                    Err(e) => stream.error = Some(e),
                }
            }
            sort_changes(&mut self.changes, &mut self.scratch);
            let n = self.changes.partition_point(|&(at, ..)| at < before);
            let m = self.at_settled.partition_point(|&(at, ..)| at < before);
            if stream.error.is_none()
                && let Some(body) = &mut stream.body
                && let Err(e) = self.write_changes(
                    &mut stream.out,
                    body,
                    &self.changes[..n],
                    &self.at_settled[..m],
                )
            {
                stream.error = Some(e);
            }
            self.changes.drain(..n);
            self.at_settled.drain(..m);
        }
        self.stream = Some(stream);
    }

    /// Sets when the simulation ended: written (clipped to the window) as a final timestamp so that
    /// viewers show how long the last values lasted.
    pub fn set_end(&mut self, at: Tick) {
        self.end = Some(at);
    }

    /// Writes the VCD text to `w` (wrap a file in a `BufWriter`: this writes in small pieces).
    ///
    /// # Panics
    ///
    /// For a streamed trace ([`VcdTrace::streamed`]), which has written its text already.
    pub fn write<W: Write>(&self, w: W) -> io::Result<()> {
        assert!(
            self.stream.is_none(),
            "a streamed VCD is written as it goes: call finish"
        );
        let mut out = vcd::Writer::new(w);
        let mut body = self.begin_body(&mut out)?;
        let mut changes = self.changes.clone();
        sort_changes(&mut changes, &mut Vec::new());
        // Not streamed: nothing is held as settled.
        self.write_changes(&mut out, &mut body, &changes, &[])?;
        self.end_body(&mut out, &body)
    }

    /// The header, then `$dumpvars` with the initial values at the window start.
    fn begin_body<W: Write>(&self, out: &mut vcd::Writer<W>) -> io::Result<Body> {
        // No version number: a release should not change every golden file.
        out.version("pxpl5-trace")?;
        out.comment("timestamps are simulated time in picoseconds, not host time")?;
        if self.window != TraceWindow::all() {
            out.comment(&format!("trace window {}", self.window))?;
        }
        for c in &self.comments {
            out.comment(c)?;
        }
        out.timescale(1, TimescaleUnit::PS)?;
        for scope in &self.scopes {
            out.add_module(&vcd_name(&scope.name))?;
            for &index in &scope.signals {
                let s = &self.signals[index];
                let range = (s.width > 1).then(|| ReferenceIndex::Range(s.width as i32 - 1, 0));
                let (kind, width) = match s.width {
                    0 => (VarType::String, 1),
                    w => (VarType::Wire, w),
                };
                out.var_def(kind, width, id_code(index), &vcd_name(&s.name), range)?;
            }
            out.upscope()?;
        }
        out.enddefinitions()?;

        let current: Vec<u64> = self
            .signals
            .iter()
            .map(|s| s.initial.map_or(0, |(_, v)| v))
            .collect();
        let mut body = Body {
            tails: (0..self.signals.len())
                .map(|i| format!("{}\n", id_code(i)).into_bytes().into_boxed_slice())
                .collect(),
            lines: vec![Vec::new(); self.signals.len()],
            current,
            last_time: self.window.start,
            text: Vec::new(),
        };
        out.timestamp(self.window.start.as_ps())?;
        out.begin(SimulationCommand::Dumpvars)?;
        for index in 0..body.current.len() {
            let value = body.current[index];
            self.encode_value(&mut body, index, value);
        }
        out.writer().write_all(&body.text)?;
        body.text.clear();
        out.end()?;
        Ok(body)
    }

    /// Writes `changes`, sorted by [`sort_changes`], merged with `settled`, the changes held at
    /// the settled instant (see [`VcdTrace::at_settled`]): together they hold every change at
    /// each instant they cover. Per wire and instant the last one recorded is written, where it
    /// changes the wire's value.
    fn write_changes<W: Write>(
        &self,
        out: &mut vcd::Writer<W>,
        body: &mut Body,
        changes: &[Change],
        settled: &[Change],
    ) -> io::Result<()> {
        let key = |c: &Change| (c.0, c.1);
        let mut n = itoa::Buffer::new();
        let (mut i, mut j) = (0, 0);
        loop {
            // The settled changes before the next one held ahead need no merging: most of them
            // (a ring token's position, at every instant), in a run.
            let bound = changes.get(i).map_or((Tick(u64::MAX), usize::MAX), key);
            let run = settled[j..].partition_point(|c| key(c) < bound);
            let end = j + run;
            while j < end {
                j += write_run(&settled[j..end], body, &mut n);
                if j < end {
                    // A change the run could not take: the text is full, or its line is not kept.
                    let (at, index, value) = settled[j];
                    j += 1;
                    self.write_change(out, body, &mut n, at, index, value)?;
                }
            }
            let from_settled = match (changes.get(i), settled.get(j)) {
                (None, None) => break,
                (Some(a), Some(b)) => key(b) <= key(a),
                (a, _) => a.is_none(),
            };
            let (at, index, value) = if from_settled {
                let c = settled[j];
                j += 1;
                // Held in `changes` at the same instant and wire: recorded before it.
                while changes.get(i).is_some_and(|a| key(a) == key(&c)) {
                    i += 1;
                }
                c
            } else {
                // The last recorded of its instant and wire (`settled` holds none of them:
                // its next is later).
                let mut c = changes[i];
                i += 1;
                while let Some(&a) = changes.get(i)
                    && key(&a) == key(&c)
                {
                    c = a;
                    i += 1;
                }
                c
            };
            self.write_change(out, body, &mut n, at, index, value)?;
        }
        out.writer().write_all(&body.text)?;
        body.text.clear();
        Ok(())
    }

    /// Writes wire `index` taking `value` at `at`, the last change recorded there, if it
    /// changes the wire's value; sends the text to `out` once it holds 64 KiB.
    #[inline(always)]
    fn write_change<W: Write>(
        &self,
        out: &mut vcd::Writer<W>,
        body: &mut Body,
        n: &mut itoa::Buffer,
        at: Tick,
        index: usize,
        value: u64,
    ) -> io::Result<()> {
        if body.current[index] == value {
            return Ok(());
        }
        if at != body.last_time {
            // As `vcd::Writer::timestamp` writes it.
            body.text.push(b'#');
            body.text.extend_from_slice(n.format(at.as_ps()).as_bytes());
            body.text.push(b'\n');
            body.last_time = at;
        }
        self.encode_value(body, index, value);
        body.current[index] = value;
        if body.text.len() >= 1 << 16 {
            out.writer().write_all(&body.text)?;
            body.text.clear();
        }
        Ok(())
    }

    /// The end's timestamp (clipped to the window), then a flush of the writer.
    fn end_body<W: Write>(&self, out: &mut vcd::Writer<W>, body: &Body) -> io::Result<()> {
        if let Some(end) = self.end {
            let end = end.min(self.window.end);
            if end > body.last_time {
                out.timestamp(end.as_ps())?;
            }
        }
        out.flush()
    }
}

/// Writes the changes of `run` (sorted, one per instant and wire) as
/// [`VcdTrace::write_change`] does, as long as each one's line is kept and the text holds less
/// than 64 KiB; returns how many it wrote. The loop of a flush: most changes are a ring token's
/// position, held at the settled instant in a run, and this keeps the body's state in registers
/// (through `write_change`, a change took about 70 instructions, most of them loads and stores
/// of it).
#[inline(never)]
fn write_run(run: &[Change], body: &mut Body, n: &mut itoa::Buffer) -> usize {
    let Body {
        current,
        last_time,
        lines,
        text,
        ..
    } = body;
    let mut last = *last_time;
    let mut done = 0;
    for &(at, index, value) in run {
        if text.len() >= 1 << 16 {
            break;
        }
        let Some(line) = lines[index].get(value as usize).filter(|l| l.len != 0) else {
            break;
        };
        done += 1;
        let current = &mut current[index];
        if *current == value {
            continue;
        }
        *current = value;
        if at != last {
            // As `vcd::Writer::timestamp` writes it.
            text.push(b'#');
            text.extend_from_slice(n.format(at.as_ps()).as_bytes());
            text.push(b'\n');
            last = at;
        }
        let end = text.len() + line.len as usize;
        text.extend_from_slice(&line.bytes);
        text.truncate(end);
    }
    *last_time = last;
    done
}

/// Changes at one instant ([`VcdTrace::sample`]).
pub struct Sample<'a> {
    at: Tick,
    /// Whether `at` is a streamed trace's settled instant, inside the window after its start:
    /// each change is then held in [`VcdTrace::at_settled`] with no other check.
    settled: bool,
    trace: &'a mut VcdTrace,
}

impl Sample<'_> {
    /// Records that `signal` takes `value` at the sample's instant: [`VcdTrace::change`].
    #[inline(always)]
    pub fn change(&mut self, signal: SignalId, value: u64) {
        if self.settled {
            let value = mask(value, self.trace.signals[signal.0].width);
            hold_settled(&mut self.trace.at_settled, (self.at, signal.0, value));
        } else {
            self.trace.change(signal, self.at, value);
        }
    }

    /// [`Sample::change`] to a text named by [`VcdTrace::text_value`].
    #[inline(always)]
    pub fn change_to(&mut self, signal: SignalId, value: TextValue) {
        self.change(signal, value.0);
    }
}

/// Holds `change`, at the settled instant, in `settled` (the [`VcdTrace::at_settled`] list): after the
/// changes of the same instant to later wires, which a recorder sampling its wires in turn
/// records after it, so the walk back is short; in place of one at the same instant and wire.
#[inline(always)]
fn hold_settled(settled: &mut Vec<Change>, change: Change) {
    let key = |c: &Change| (c.0, c.1);
    if settled.last().is_none_or(|last| key(last) < key(&change)) {
        settled.push(change);
        return;
    }
    let mut i = settled.len();
    while i > 0 && key(&settled[i - 1]) > key(&change) {
        i -= 1;
    }
    match i.checked_sub(1).map(|k| &mut settled[k]) {
        Some(same) if key(same) == key(&change) => same.2 = change.2,
        _ => settled.insert(i, change),
    }
}

/// Changes in the order they are written: by time, then wire creation order. Stable, so changes
/// to one wire at one instant stay in the order they are held in, which is recording order (the
/// changes a flush kept are sorted and older than any recorded after it), and the last wins.
///
/// A least-significant-digit radix sort, a byte at a time, by wire and then by time since the
/// batch's first instant, skipping the bytes every change shares: a batch spans little time,
/// so a few passes suffice. The standard library's stable sort took two thirds of a streamed
/// VCD's cost (188 M instructions for the 5 batches of 65,536 changes of a 20-shot radiosity
/// run).
fn sort_changes(changes: &mut Vec<Change>, scratch: &mut Vec<Change>) {
    if changes.len() < 64 {
        changes.sort_by_key(|&(at, index, _)| (at, index));
        return;
    }
    let min = changes.iter().map(|c| c.0.as_ps()).min().unwrap_or(0);
    let max_dt = changes.iter().map(|c| c.0.as_ps() - min).max().unwrap_or(0);
    let max_index = changes.iter().map(|c| c.1 as u64).max().unwrap_or(0);
    // The bytes that can differ: those of the largest wire number and time offset.
    let bytes = |max: u64| (64 - max.leading_zeros()).div_ceil(8);
    let passes = (0..bytes(max_index))
        .map(|k| (false, 8 * k))
        .chain((0..bytes(max_dt)).map(|k| (true, 8 * k)));
    // Each pass moves the changes from one buffer to the other; the buffers trade places.
    scratch.clear();
    scratch.resize(changes.len(), (Tick::ZERO, 0, 0));
    let (src, dst) = (changes, scratch);
    for (by_time, shift) in passes {
        let digit = |c: &Change| {
            let key = if by_time {
                c.0.as_ps() - min
            } else {
                c.1 as u64
            };
            (key >> shift) as usize & 0xff
        };
        let mut counts = [0usize; 256];
        for c in src.iter() {
            counts[digit(c)] += 1;
        }
        if counts.contains(&src.len()) {
            // Every change has this byte: the pass would keep the order.
            continue;
        }
        let mut at = 0;
        for n in counts.iter_mut() {
            (*n, at) = (at, at + *n);
        }
        for &c in src.iter() {
            let d = digit(&c);
            dst[counts[d]] = c;
            counts[d] += 1;
        }
        std::mem::swap(src, dst);
    }
}

/// The whole VCD text (what [`VcdTrace::write`] writes).
impl fmt::Display for VcdTrace {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut bytes = Vec::new();
        self.write(&mut bytes).map_err(|_| fmt::Error)?;
        f.write_str(std::str::from_utf8(&bytes).map_err(|_| fmt::Error)?)
    }
}

impl VcdTrace {
    /// Appends wire `index` taking `value` to the body's text, as `vcd::Writer`'s
    /// `change_scalar`, `change_vector` (every bit, most significant first, so the text reads
    /// like the number) and `change_string` write it, by hand: through the crate, the
    /// formatting machinery was most of the trace's cost (a 60-shot radiosity run took 28 %
    /// more instructions with `--vcd`).
    #[inline]
    fn encode_value(&self, body: &mut Body, index: usize, value: u64) {
        // Most lines are kept (a ring token's position, a busy wire): a copy and a truncation.
        if let Some(line) = body.lines[index].get(value as usize)
            && line.len != 0
        {
            let end = body.text.len() + line.len as usize;
            body.text.extend_from_slice(&line.bytes);
            body.text.truncate(end);
            return;
        }
        self.encode_value_first(body, index, value);
    }

    /// [`VcdTrace::encode_value`] for a line not kept: made now, and kept if it may be.
    #[cold]
    fn encode_value_first(&self, body: &mut Body, index: usize, value: u64) {
        let width = self.signals[index].width;
        // A text index held by no text (a raw `change` to a string variable) writes `_`, and
        // is not kept: the index may name a text interned later. Wider wires keep no lines.
        let kept = match width {
            0 => value < self.texts.len() as u64,
            1 => true,
            _ => false,
        };
        let text = self.value_line(&body.tails[index], width, value);
        let made = Line::new(&text);
        if let Some(line) = made
            && kept
        {
            let lines = &mut body.lines[index];
            let v = value as usize;
            if lines.len() <= v {
                lines.resize(v + 1, Line::NONE);
            }
            lines[v] = line;
        }
        body.text.extend_from_slice(&text);
    }

    /// The line of a wire of `width` bits taking `value`, ending in `tail` (see
    /// [`VcdTrace::encode_value`]).
    fn value_line(&self, tail: &[u8], width: u32, value: u64) -> Vec<u8> {
        let mut line = Vec::with_capacity(width as usize + tail.len() + 2);
        match width {
            0 => {
                line.push(b's');
                let value = self.texts.get(value as usize).map_or("_", String::as_str);
                line.extend_from_slice(value.as_bytes());
                line.push(b' ');
            }
            1 => line.push(b'0' + (value & 1) as u8),
            width => {
                line.push(b'b');
                line.extend(
                    (0..width)
                        .rev()
                        .map(|bit| b'0' + ((value >> bit) & 1) as u8),
                );
                line.push(b' ');
            }
        }
        line.extend_from_slice(tail);
        line
    }
}

fn id_code(index: usize) -> IdCode {
    IdCode::from(index as u64)
}

#[inline(always)]
fn mask(value: u64, width: u32) -> u64 {
    // Width 0 is a string variable: its value is an index, never masked. A wire is 1 to
    // MAX_WIDTH bits, so (64 - width) mod 64 is the shift for every width, 0 and 64 giving the
    // whole value: no branch, in a call made at every change.
    debug_assert!(width <= MAX_WIDTH);
    value & (u64::MAX >> (64u32.wrapping_sub(width) & 63))
}

/// `name` as a VCD name: printable ASCII other than space kept, everything else `_`.
fn vcd_name(name: &str) -> String {
    if name.is_empty() {
        return "_".to_owned();
    }
    name.chars()
        .map(|c| if c.is_ascii_graphic() { c } else { '_' })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_hold_no_whitespace() {
        assert_eq!(vcd_name("GP 0"), "GP_0");
        assert_eq!(vcd_name("ch\t2\n"), "ch_2_");
        assert_eq!(vcd_name("µs"), "_s");
        assert_eq!(vcd_name(""), "_");
        assert_eq!(vcd_name("data[7]"), "data[7]");
    }

    #[test]
    fn values_are_masked_to_the_width() {
        assert_eq!(mask(0x1ff, 8), 0xff);
        assert_eq!(mask(3, 1), 1);
        assert_eq!(mask(u64::MAX, 64), u64::MAX);
        assert_eq!(mask(u64::MAX, 63), u64::MAX >> 1);
        // A string variable's value, a text's index, is kept whole.
        assert_eq!(mask(u64::MAX - 1, 0), u64::MAX - 1);
        for width in 1..64 {
            assert_eq!(mask(u64::MAX, width), (1 << width) - 1, "width {width}");
        }
    }

    /// The radix sort is the standard library's stable sort by (time, wire): on batches shaped
    /// like a recorder's (changes now and at the ends of spans ahead, a few wires, ties at one
    /// instant with different values), on wide time spans and wire numbers, and below and above
    /// the size where it switches.
    #[test]
    fn the_radix_sort_is_the_stable_sort() {
        let mut next = pxpl5_tests::xorshift(0x0123_4567_89AB_CDEF);
        for (len, span, wires) in [
            (10, 100, 3),
            (63, 1_000, 5),
            (64, 1_000, 5),
            (5_000, 3_000, 40),
            (5_000, u64::MAX / 2, 1 << 20),
            (20_000, 1 << 30, usize::MAX / 3),
        ] {
            let mut now = 1_000u64;
            let changes: Vec<Change> = (0..len)
                .map(|i| {
                    let r = next();
                    now += r % 4;
                    let at = if r.is_multiple_of(3) {
                        now + (r >> 8) % span
                    } else {
                        now
                    };
                    let wire = (r >> 16) as usize % wires;
                    (Tick(at.min(u64::MAX - 1)), wire, i as u64)
                })
                .collect();
            let mut expected = changes.clone();
            expected.sort_by_key(|&(at, index, _)| (at, index));
            let mut radix = changes;
            sort_changes(&mut radix, &mut Vec::new());
            assert_eq!(radix, expected, "{len} changes");
        }
    }
}
