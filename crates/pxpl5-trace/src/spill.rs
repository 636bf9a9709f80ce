//! [`ExternalSort`]: records kept in order with bounded memory, the home of the JSON trace's
//! sort. A Chrome trace is written in timestamp order but recorded in any order (a machine's
//! critical path is known only at its end), so its events are sorted before they are written.
//! Held in memory they grow with the run; here, past a budget of bytes, the records held are
//! sorted and written to an anonymous temporary file (a *run*), and the output is the k-way
//! merge of the runs and what is still held. The order is the keys' own (`Ord`, total), so the
//! output does not depend on the budget, on where the runs went, or on whether anything was
//! spilled at all.
//!
//! A record is a key and a payload of bytes. Held records' payloads share one buffer, and a
//! run's are read into one buffer per run, so neither recording nor merging allocates per
//! record.

use std::cmp::{Ordering, Reverse};
use std::collections::BinaryHeap;
use std::fs::File;
use std::io::{self, BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::PathBuf;

/// A record's key: its place in the order, written to a run in `BYTES` bytes of its own
/// format (runs live only as long as the sort).
pub(crate) trait SortKey: Ord + Copy {
    /// The size of the key in a run.
    const BYTES: usize;
    /// Writes the key into `out` (`BYTES` long).
    fn put(&self, out: &mut [u8]);
    /// Reads a key written by `put`.
    fn get(bytes: &[u8]) -> Self;
}

/// Records sorted by key with at most about `budget` bytes of them held in memory, the rest in
/// runs in a directory; without a directory, everything is held (the default: a small trace, a
/// test).
#[derive(Debug)]
pub(crate) struct ExternalSort<K> {
    /// The held records: key, and where the payload lies in `payloads`.
    held: Vec<(K, u32, u32)>,
    payloads: Vec<u8>,
    budget: usize,
    dir: Option<PathBuf>,
    runs: Vec<File>,
    /// The first error of a spill: a recorder's calls return nothing, so it waits for the
    /// output, which then fails with it.
    error: Option<io::Error>,
}

impl<K> Default for ExternalSort<K> {
    fn default() -> ExternalSort<K> {
        ExternalSort {
            held: Vec::new(),
            payloads: Vec::new(),
            budget: usize::MAX,
            dir: None,
            runs: Vec::new(),
            error: None,
        }
    }
}

impl<K: SortKey> ExternalSort<K> {
    /// A sort that spills runs to anonymous files in `dir` once it holds more than `budget`
    /// bytes.
    pub(crate) fn spilling(dir: PathBuf, budget: usize) -> ExternalSort<K> {
        ExternalSort {
            budget,
            dir: Some(dir),
            ..ExternalSort::default()
        }
    }

    /// A sort like this one (same directory, same budget), empty.
    pub(crate) fn like(&self) -> ExternalSort<K> {
        ExternalSort {
            budget: self.budget,
            dir: self.dir.clone(),
            ..ExternalSort::default()
        }
    }

    /// Adds a record. A payload is at most 4 GiB (a trace event's text is far less).
    pub(crate) fn push(&mut self, key: K, payload: &[u8]) {
        let (at, len) = (self.payloads.len(), payload.len());
        let (Ok(at), Ok(len)) = (u32::try_from(at), u32::try_from(len)) else {
            // More than 4 GiB of payloads held: only a sort without a directory gets here.
            self.error.get_or_insert_with(|| {
                io::Error::new(
                    io::ErrorKind::OutOfMemory,
                    "over 4 GiB of trace events held",
                )
            });
            return;
        };
        if self.payloads.capacity() == 0 && self.dir.is_some() {
            // Once, at its size: grown by doubling, the buffer could hold twice the budget.
            self.payloads.reserve_exact(self.budget.min(1 << 30));
        }
        self.payloads.extend_from_slice(payload);
        self.held.push((key, at, len));
        if self.held() > self.budget
            && self.dir.is_some()
            && self.error.is_none()
            && let Err(e) = self.spill()
        {
            self.error = Some(e);
        }
    }

    /// How many runs went to disk.
    pub(crate) fn runs(&self) -> usize {
        self.runs.len()
    }

    /// The bytes of records held in memory now.
    pub(crate) fn held(&self) -> usize {
        self.held.len() * std::mem::size_of::<(K, u32, u32)>() + self.payloads.len()
    }

    fn spill(&mut self) -> io::Result<()> {
        let Some(dir) = &self.dir else {
            return Ok(());
        };
        self.held.sort_unstable_by_key(|r| r.0);
        let file = tempfile::tempfile_in(dir)?;
        let mut w = BufWriter::with_capacity(1 << 16, &file);
        let mut key = vec![0u8; K::BYTES];
        for &(k, at, len) in &self.held {
            k.put(&mut key);
            w.write_all(&key)?;
            w.write_all(&len.to_le_bytes())?;
            w.write_all(&self.payloads[at as usize..(at + len) as usize])?;
        }
        w.flush()?;
        drop(w);
        self.runs.push(file);
        self.held.clear();
        self.payloads.clear();
        Ok(())
    }
}

/// Where a merge takes records from: a sort's held records in key order, or a run, with the
/// record read last.
enum Source<'a, K> {
    Held {
        sort: &'a ExternalSort<K>,
        order: Vec<u32>,
        next: usize,
    },
    Run {
        reader: BufReader<&'a File>,
        head: Vec<u8>,
        payload: Vec<u8>,
    },
}

impl<K: SortKey> Source<'_, K> {
    /// Moves to the next record; its key, `None` at the end.
    fn advance(&mut self) -> io::Result<Option<K>> {
        match self {
            Source::Held { sort, order, next } => {
                let key = order.get(*next).map(|&i| sort.held[i as usize].0);
                *next += 1;
                Ok(key)
            }
            Source::Run {
                reader,
                head,
                payload,
            } => {
                if !read_or_end(reader, head)? {
                    return Ok(None);
                }
                let len = u32::from_le_bytes(head[K::BYTES..].try_into().expect("4 bytes"));
                payload.resize(len as usize, 0);
                if !read_or_end(reader, payload)? && len > 0 {
                    return Err(truncated());
                }
                Ok(Some(K::get(&head[..K::BYTES])))
            }
        }
    }

    /// The payload of the record `advance` moved to.
    fn payload(&self) -> &[u8] {
        match self {
            Source::Held { sort, order, next } => {
                let (_, at, len) = sort.held[order[*next - 1] as usize];
                &sort.payloads[at as usize..(at + len) as usize]
            }
            Source::Run { payload, .. } => payload,
        }
    }
}

/// The head of one source in the merge's heap.
struct Head<K> {
    key: K,
    source: usize,
}

impl<K: Ord> PartialEq for Head<K> {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl<K: Ord> Eq for Head<K> {}
impl<K: Ord> PartialOrd for Head<K> {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl<K: Ord> Ord for Head<K> {
    fn cmp(&self, other: &Self) -> Ordering {
        self.key
            .cmp(&other.key)
            .then(self.source.cmp(&other.source))
    }
}

/// Calls `f` with every record of `sorts` in key order: their runs and held records merged.
/// Fails with the first spill error, if any, a run's read error, or `f`'s.
pub(crate) fn merge<K: SortKey>(
    sorts: &[&ExternalSort<K>],
    mut f: impl FnMut(K, &[u8]) -> io::Result<()>,
) -> io::Result<()> {
    let mut sources = Vec::new();
    for &sort in sorts {
        if let Some(e) = &sort.error {
            return Err(io::Error::new(
                e.kind(),
                format!("cannot spill the trace: {e}"),
            ));
        }
        for run in &sort.runs {
            let mut file = run;
            file.seek(SeekFrom::Start(0))?;
            sources.push(Source::Run {
                reader: BufReader::with_capacity(1 << 16, run),
                head: vec![0; K::BYTES + 4],
                payload: Vec::new(),
            });
        }
        let mut order: Vec<u32> = (0..sort.held.len() as u32).collect();
        order.sort_unstable_by(|&a, &b| sort.held[a as usize].0.cmp(&sort.held[b as usize].0));
        sources.push(Source::Held {
            sort,
            order,
            next: 0,
        });
    }
    let mut heap = BinaryHeap::with_capacity(sources.len());
    for (source, s) in sources.iter_mut().enumerate() {
        if let Some(key) = s.advance()? {
            heap.push(Reverse(Head { key, source }));
        }
    }
    while let Some(Reverse(Head { key, source })) = heap.pop() {
        f(key, sources[source].payload())?;
        if let Some(key) = sources[source].advance()? {
            heap.push(Reverse(Head { key, source }));
        }
    }
    Ok(())
}

fn truncated() -> io::Error {
    io::Error::new(
        io::ErrorKind::UnexpectedEof,
        "a trace spill file ends inside a record",
    )
}

/// Reads exactly `buf.len()` bytes, or none at a clean end of the run (`Ok(false)`).
fn read_or_end(r: &mut impl Read, buf: &mut [u8]) -> io::Result<bool> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) if got == 0 => return Ok(false),
            Ok(0) => return Err(truncated()),
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    impl SortKey for u64 {
        const BYTES: usize = 8;
        fn put(&self, out: &mut [u8]) {
            out.copy_from_slice(&self.to_le_bytes());
        }
        fn get(bytes: &[u8]) -> u64 {
            u64::from_le_bytes(bytes.try_into().unwrap())
        }
    }

    /// Every record, as (key, payload).
    fn sorted(sorts: &[&ExternalSort<u64>]) -> Vec<(u64, Vec<u8>)> {
        let mut out = Vec::new();
        merge(sorts, |k, p| {
            out.push((k, p.to_vec()));
            Ok(())
        })
        .unwrap();
        out
    }

    #[test]
    fn spilled_runs_merge_into_the_same_order_as_memory() {
        // A scrambled sequence of distinct keys (multiplication by an odd constant permutes
        // u64), payloads of 0 to 4 bytes.
        let records: Vec<(u64, Vec<u8>)> = (0..1000u64)
            .map(|i| {
                (
                    i.wrapping_mul(0x9e37_79b9_7f4a_7c15),
                    vec![i as u8; (i % 5) as usize],
                )
            })
            .collect();
        let mut memory = ExternalSort::default();
        let budget = 16 * 64;
        let mut spilled = ExternalSort::spilling(std::env::temp_dir(), budget);
        for (k, p) in &records {
            memory.push(*k, p);
            spilled.push(*k, p);
            assert!(spilled.held() <= budget);
        }
        assert_eq!(memory.runs(), 0);
        assert!(spilled.runs() > 10, "{} runs", spilled.runs());
        let mut expected = records.clone();
        expected.sort_unstable();
        assert_eq!(sorted(&[&memory]), expected);
        assert_eq!(sorted(&[&spilled]), expected);
        // The runs are read again from their start by a second merge.
        assert_eq!(sorted(&[&spilled]), expected);
    }

    #[test]
    fn two_sorts_merge_as_one() {
        let mut a = ExternalSort::spilling(std::env::temp_dir(), 40);
        let mut b = a.like();
        for v in [5u64, 1, 9, 3, 7] {
            a.push(v, &[]);
        }
        for v in [4u64, 8, 2, 6, 0] {
            b.push(v, &[v as u8]);
        }
        let keys: Vec<u64> = sorted(&[&a, &b]).into_iter().map(|(k, _)| k).collect();
        assert_eq!(keys, (0..10).collect::<Vec<_>>());
    }

    #[test]
    fn a_spill_error_is_returned_by_the_merge() {
        let mut s = ExternalSort::spilling(PathBuf::from("/nonexistent/pxpl5-spill"), 8);
        s.push(1u64, &[]);
        s.push(2u64, &[]);
        let e = merge(&[&s], |_, _| Ok(())).expect_err("the spill failed");
        assert!(e.to_string().contains("cannot spill the trace"), "{e}");
    }

    #[test]
    fn a_truncated_run_is_an_error() {
        let mut r: &[u8] = &[1, 2, 3];
        let mut b = [0; 8];
        assert!(read_or_end(&mut r, &mut b).is_err());
        let mut empty: &[u8] = &[];
        assert!(!read_or_end(&mut empty, &mut b).unwrap());
    }
}
