//! The deterministic event queue: every pending event of the simulation, popped in order of
//! (tick, priority, component, sequence number).
//!
//! Each key exists so that no two pending events ever compare equal, which is what makes a run
//! reproducible: the tick is simulated time; the [`Priority`] fixes the order of classes of events
//! within one tick (which classes there are, and why they come in that order, is the business of
//! the simulator that schedules them); the [`ComponentId`] fixes the order of components acting in
//! the same class; and the sequence
//! number, unique per `schedule` call, keeps events of the same component in the order they were
//! scheduled (FIFO). Nothing depends on host addresses, hashing or thread timing.

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::fmt;

use crate::time::Tick;

/// Names a simulated component (any unit of the simulated machine). Its number is the tie-break
/// between components acting at the same tick and priority, so components must be numbered
/// deterministically (for instance in configuration order).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ComponentId(pub u32);

impl fmt::Display for ComponentId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "component {}", self.0)
    }
}

/// The class of an event within its tick: at the same tick, lower classes pop first.
///
/// The kernel gives classes no meaning. The simulator that schedules events names its classes as
/// constants and documents why they are ordered as they are (for instance, a completion that frees
/// a resource before the work that wants it): that order is part of its timing semantics. A class
/// is a plain number so that this crate names nothing of the machine it simulates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Priority(pub u8);

impl fmt::Display for Priority {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "class {}", self.0)
    }
}

/// An event scheduled before the queue's current time: it could never happen on time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PastEvent {
    /// Who scheduled it.
    pub component: ComponentId,
    /// Its class.
    pub priority: Priority,
    /// When it was to happen.
    pub tick: Tick,
    /// The queue's current time, after `tick`.
    pub now: Tick,
}

impl fmt::Display for PastEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} scheduled an event of {} at {}, before the current time {}",
            self.component, self.priority, self.tick, self.now
        )
    }
}

impl std::error::Error for PastEvent {}

/// One scheduled event, as popped from an [`EventQueue`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Event<T> {
    /// When it happens.
    pub tick: Tick,
    /// Its class within the tick.
    pub priority: Priority,
    /// The component it is addressed to (and the tie-break within the class).
    pub component: ComponentId,
    /// The sequence number `schedule` returned: the FIFO tie-break.
    pub seq: u64,
    /// What the component is to do.
    pub payload: T,
}

/// The ordering key of a pending event. Its `Ord` is reversed, because `BinaryHeap` is a
/// max-heap and the queue must pop the smallest key first. Kept apart from the payload so
/// that the payload never needs `Ord`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Key {
    tick: Tick,
    /// Priority above component, so that the order within a tick is two u64 comparisons, not
    /// a chain of three (a pop compares keys at every level of the heap; the machine pops about
    /// one event an instant). Not one u128 with the sequence number: the entries, aligned to
    /// 16 bytes, were written in pieces that the pop's next read spans (a store-to-load
    /// forwarding stall, by its hottest instruction), and pops took 3.9 % of the main job's
    /// hemicube in CPU time (`perf record -e cpu-clock`); 1.6 % as three u64s.
    class: u64,
    seq: u64,
}

impl Key {
    fn new(tick: Tick, priority: Priority, component: ComponentId, seq: u64) -> Key {
        let class = u64::from(priority.0) << 32 | u64::from(component.0);
        Key { tick, class, seq }
    }

    fn priority(self) -> Priority {
        Priority((self.class >> 32) as u8)
    }

    fn component(self) -> ComponentId {
        ComponentId(self.class as u32)
    }

    fn seq(self) -> u64 {
        self.seq
    }
}

impl Ord for Key {
    fn cmp(&self, other: &Self) -> Ordering {
        // Reversed (other against self) to turn the max-heap into a min-heap.
        (other.tick, other.class, other.seq).cmp(&(self.tick, self.class, self.seq))
    }
}

impl PartialOrd for Key {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// A heap entry: the key, which alone decides the order, and the payload along for the ride.
/// Two entries are equal exactly when their keys are, which only happens for the same entry
/// since sequence numbers are unique.
#[derive(Debug)]
struct Entry<T> {
    key: Key,
    payload: T,
}

impl<T> PartialEq for Entry<T> {
    fn eq(&self, other: &Self) -> bool {
        self.key == other.key
    }
}

impl<T> Eq for Entry<T> {}

impl<T> Ord for Entry<T> {
    fn cmp(&self, other: &Self) -> Ordering {
        self.key.cmp(&other.key)
    }
}

impl<T> PartialOrd for Entry<T> {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// The pending events of a simulation, popped in order of (tick, priority, component, seq).
#[derive(Debug)]
pub struct EventQueue<T> {
    heap: BinaryHeap<Entry<T>>,
    /// The next sequence number to hand out; u64 cannot wrap in any feasible run.
    next_seq: u64,
    /// Tick of the last popped event: the simulation has reached it, so nothing may be
    /// scheduled before it.
    now: Tick,
}

impl<T> Default for EventQueue<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T> EventQueue<T> {
    /// An empty queue at time zero.
    pub fn new() -> Self {
        EventQueue {
            heap: BinaryHeap::new(),
            next_seq: 0,
            now: Tick::ZERO,
        }
    }

    /// Schedules `payload` for `component` at `tick` in class `priority`, and returns its
    /// sequence number (0 for the first call, then one more per call).
    ///
    /// Scheduling at `now()` is allowed (a component reacting within the same tick); the new
    /// event pops after every pending event with a smaller key, and if its priority is lower
    /// than that of the event being handled it still pops next, not retroactively.
    ///
    /// # Panics
    ///
    /// If `tick` is earlier than [`EventQueue::now`]: the simulation has already passed it, so
    /// the event could never happen on time. That is a bug in the simulator, not a condition
    /// to recover from ([`EventQueue::try_schedule`] reports it instead).
    pub fn schedule(
        &mut self,
        tick: Tick,
        priority: Priority,
        component: ComponentId,
        payload: T,
    ) -> u64 {
        self.try_schedule(tick, priority, component, payload)
            .unwrap_or_else(|e| panic!("{e}"))
    }

    /// [`EventQueue::schedule`], returning the event in the past as an error instead of
    /// panicking (the queue is unchanged then).
    pub fn try_schedule(
        &mut self,
        tick: Tick,
        priority: Priority,
        component: ComponentId,
        payload: T,
    ) -> Result<u64, PastEvent> {
        if tick < self.now {
            return Err(PastEvent {
                component,
                priority,
                tick,
                now: self.now,
            });
        }
        let seq = self.next_seq;
        self.next_seq += 1;
        self.heap.push(Entry {
            key: Key::new(tick, priority, component, seq),
            payload,
        });
        Ok(seq)
    }

    /// Removes and returns the pending event with the smallest (tick, priority, component,
    /// seq), and advances [`EventQueue::now`] to its tick.
    pub fn pop(&mut self) -> Option<Event<T>> {
        let Entry { key, payload } = self.heap.pop()?;
        self.now = key.tick;
        Some(Event {
            tick: key.tick,
            priority: key.priority(),
            component: key.component(),
            seq: key.seq(),
            payload,
        })
    }

    /// The tick of the next event to pop, if any.
    pub fn peek_tick(&self) -> Option<Tick> {
        self.heap.peek().map(|e| e.key.tick)
    }

    /// The number of pending events.
    pub fn len(&self) -> usize {
        self.heap.len()
    }

    /// Whether no event is pending.
    pub fn is_empty(&self) -> bool {
        self.heap.is_empty()
    }

    /// The tick of the last popped event (zero before the first pop).
    pub fn now(&self) -> Tick {
        self.now
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const C0: ComponentId = ComponentId(0);
    const C1: ComponentId = ComponentId(1);
    /// The lowest and highest classes the tests use.
    const FIRST: Priority = Priority(0);
    const LAST: Priority = Priority(4);

    /// Pops everything, keeping the payloads, to compare orders compactly.
    fn drain<T>(q: &mut EventQueue<T>) -> Vec<T> {
        std::iter::from_fn(|| q.pop()).map(|e| e.payload).collect()
    }

    #[test]
    fn empty_queue() {
        let mut q: EventQueue<()> = EventQueue::new();
        assert!(q.is_empty());
        assert_eq!(q.len(), 0);
        assert_eq!(q.peek_tick(), None);
        assert_eq!(q.now(), Tick::ZERO);
        assert!(q.pop().is_none());
        // Popping nothing must not move time.
        assert_eq!(q.now(), Tick::ZERO);
    }

    #[test]
    fn orders_by_tick_first() {
        let mut q = EventQueue::new();
        // Later tick but every other key smaller: the tick must still win.
        q.schedule(Tick(200), FIRST, C0, "late");
        q.schedule(Tick(100), LAST, ComponentId(9), "early");
        assert_eq!(q.peek_tick(), Some(Tick(100)));
        assert_eq!(drain(&mut q), ["early", "late"]);
    }

    #[test]
    fn orders_by_priority_within_a_tick() {
        let mut q = EventQueue::new();
        // Scheduled in reverse class order, from a larger component number downwards, so
        // neither seq nor component can produce the expected order.
        let classes = [LAST, Priority(3), Priority(2), Priority(1), FIRST];
        for (i, p) in classes.into_iter().enumerate() {
            q.schedule(Tick(10), p, ComponentId(i as u32), p);
        }
        assert_eq!(
            drain(&mut q),
            [FIRST, Priority(1), Priority(2), Priority(3), LAST,]
        );
    }

    #[test]
    fn classes_order_by_number() {
        assert!(Priority(0) < Priority(1));
        assert!(Priority(1) < Priority(255));
        assert_eq!(Priority(3).to_string(), "class 3");
    }

    #[test]
    fn orders_by_component_within_a_class() {
        let mut q = EventQueue::new();
        for c in [7, 3, 5, 0] {
            q.schedule(Tick(10), Priority(3), ComponentId(c), c);
        }
        assert_eq!(drain(&mut q), [0, 3, 5, 7]);
    }

    #[test]
    fn fifo_among_equal_tick_priority_component() {
        let mut q = EventQueue::new();
        let seqs: Vec<u64> = (0..100)
            .map(|i| q.schedule(Tick(5), Priority(1), C1, i))
            .collect();
        assert_eq!(seqs, (0..100).collect::<Vec<u64>>());
        let events: Vec<Event<i32>> = std::iter::from_fn(|| q.pop()).collect();
        assert_eq!(
            events.iter().map(|e| e.payload).collect::<Vec<_>>(),
            (0..100).collect::<Vec<_>>()
        );
        assert!(events.windows(2).all(|w| w[0].seq < w[1].seq));
    }

    #[test]
    fn sequence_numbers_count_every_schedule_call() {
        let mut q = EventQueue::new();
        assert_eq!(q.schedule(Tick(3), LAST, C0, ()), 0);
        assert_eq!(q.schedule(Tick(1), FIRST, C1, ()), 1);
        q.pop();
        // Popping does not reuse or reset numbers.
        assert_eq!(q.schedule(Tick(2), FIRST, C1, ()), 2);
        assert_eq!(q.len(), 2);
    }

    #[test]
    fn event_carries_its_key() {
        let mut q = EventQueue::new();
        let seq = q.schedule(Tick(42), Priority(2), ComponentId(3), 'x');
        assert_eq!(
            q.pop(),
            Some(Event {
                tick: Tick(42),
                priority: Priority(2),
                component: ComponentId(3),
                seq,
                payload: 'x',
            })
        );
    }

    #[test]
    fn payload_needs_no_ord() {
        // f64 is not Ord and a boxed closure is not even PartialEq: both must be accepted.
        let mut q: EventQueue<Box<dyn Fn() -> f64>> = EventQueue::new();
        q.schedule(Tick(2), LAST, C0, Box::new(|| 2.5));
        q.schedule(Tick(1), LAST, C0, Box::new(|| 1.5));
        let values: Vec<f64> = drain(&mut q).iter().map(|f| f()).collect();
        assert_eq!(values, [1.5, 2.5]);
    }

    #[test]
    fn now_advances_with_pops() {
        let mut q = EventQueue::new();
        q.schedule(Tick(30), FIRST, C0, ());
        q.schedule(Tick(10), FIRST, C0, ());
        q.schedule(Tick(10), LAST, C0, ());
        assert_eq!(q.now(), Tick::ZERO);
        q.pop();
        assert_eq!(q.now(), Tick(10));
        q.pop();
        assert_eq!(q.now(), Tick(10));
        // Reacting within the current tick is allowed.
        q.schedule(Tick(10), Priority(3), C1, ());
        assert_eq!(q.peek_tick(), Some(Tick(10)));
        q.pop();
        assert_eq!(q.now(), Tick(10));
        q.pop();
        assert_eq!(q.now(), Tick(30));
        assert!(q.is_empty());
    }

    #[test]
    fn scheduling_in_the_past_is_an_error() {
        let mut q = EventQueue::new();
        q.schedule(Tick(100), FIRST, C0, ());
        q.pop();
        let e = q
            .try_schedule(Tick(99), FIRST, ComponentId(4), ())
            .unwrap_err();
        assert_eq!(
            e,
            PastEvent {
                component: ComponentId(4),
                priority: FIRST,
                tick: Tick(99),
                now: Tick(100),
            }
        );
        assert_eq!(
            e.to_string(),
            "component 4 scheduled an event of class 0 at 99 ps, before the current time 100 ps"
        );
        // Nothing was scheduled; the current time is still allowed.
        assert!(q.is_empty());
        assert_eq!(q.try_schedule(Tick(100), FIRST, C0, ()), Ok(1));
    }

    use pxpl5_geom::rng::Lcg;

    const PRIORITIES: [Priority; 5] = [FIRST, Priority(1), Priority(2), Priority(3), LAST];

    /// Schedules 10,000 events with keys drawn from small ranges (so that ties on tick,
    /// priority and component are frequent), the payload being the scheduling index, and
    /// returns them popped.
    fn scrambled_run(seed: u64) -> Vec<Event<usize>> {
        let mut rng = Lcg::new(seed);
        let mut q = EventQueue::new();
        for i in 0..10_000 {
            let tick = Tick(rng.below(200));
            let priority = PRIORITIES[(rng.below(5)) as usize];
            let component = ComponentId((rng.below(8)) as u32);
            q.schedule(tick, priority, component, i);
        }
        assert_eq!(q.len(), 10_000);
        let out: Vec<Event<usize>> = std::iter::from_fn(|| q.pop()).collect();
        assert!(q.is_empty());
        out
    }

    #[test]
    fn scrambled_events_pop_sorted_and_reproducibly() {
        let first = scrambled_run(0x5eed);
        let second = scrambled_run(0x5eed);
        assert_eq!(first.len(), 10_000);
        assert_eq!(first, second);

        let key = |e: &Event<usize>| (e.tick, e.priority, e.component, e.seq);
        // Strictly increasing: sorted, and no two events share a key.
        assert!(first.windows(2).all(|w| key(&w[0]) < key(&w[1])));

        // Every event comes out exactly once; payload i was scheduled i-th, so seq == i.
        let mut payloads: Vec<usize> = first.iter().map(|e| e.payload).collect();
        assert!(first.iter().all(|e| e.seq == e.payload as u64));
        payloads.sort_unstable();
        assert_eq!(payloads, (0..10_000).collect::<Vec<_>>());
    }

    #[test]
    fn interleaved_schedule_and_pop_never_goes_back_in_time() {
        // The simulator's real pattern: each popped event schedules follow-ups at or after now.
        let mut rng = Lcg::new(7);
        let mut q = EventQueue::new();
        q.schedule(Tick::ZERO, FIRST, C0, 0u32);
        let mut last = Tick::ZERO;
        let mut popped = 0;
        while let Some(e) = q.pop() {
            assert!(e.tick >= last);
            last = e.tick;
            popped += 1;
            if e.payload < 2_000 {
                for k in 0..2 {
                    let tick = e.tick + Tick(rng.below(3));
                    let priority = PRIORITIES[(rng.below(5)) as usize];
                    q.schedule(tick, priority, ComponentId(k), e.payload * 2 + 1 + k);
                }
            }
        }
        // Nodes 0..2000 each spawn two children (2n + 1, 2n + 2): 4,001 events in all.
        assert_eq!(popped, 4_001);
        assert_eq!(q.now(), last);
    }
}
