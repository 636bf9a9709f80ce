//! Renderer pixel work on host threads.
//!
//! A board's pixel state depends only on its commands, in order; its timing needs no pixel work
//! (every cost comes from the cycle table and the interlocks from field overlaps). So a
//! [`Board`](crate::Board) can hand its [`Pixels`] to a worker thread and go on: the machine
//! charges each command's cycles at once, and the worker applies the commands behind it. Only a
//! look at the pixels waits for the worker to catch up: a readback (its messages carry pixel
//! values), or an image or values asked for by a test or a picture. The results are those of
//! one thread by construction: each board's commands are applied in order by one thread, and
//! nothing the machine decides depends on when.
//!
//! [`Workers`] is a pool of threads (crossbeam channels); board `k` adopted by it runs on
//! thread `k mod threads`. Threads end when the pool and every board on it are dropped.

use std::cell::Cell;

use crossbeam_channel::{Receiver, Sender, unbounded};

use crate::board::{BoardImage, Pixels, ReadbackStream};
use crate::command::{Bit, Command, Field};

/// A pool of host threads that run boards' pixel work.
pub struct Workers {
    threads: Vec<Sender<Job>>,
    /// Boards adopted so far (the next one's number).
    adopted: Cell<usize>,
}

/// What a worker thread is asked to do for one of its boards.
enum Job {
    Adopt {
        board: usize,
        pixels: Box<Pixels>,
        replies: Sender<Reply>,
    },
    /// Apply a command; nothing is waited for.
    Apply { board: usize, command: Command },
    /// Answer on the board's reply channel.
    Ask { board: usize, question: Question },
    /// The board is gone: free its pixels.
    Drop { board: usize },
}

enum Question {
    /// Apply a command and send what it returned (a readback's messages).
    Apply(Command),
    Image,
    FieldValues(Field),
    BitValues(Bit),
}

enum Reply {
    Readback(Option<ReadbackStream>),
    Image(BoardImage),
    Values(Vec<u64>),
    Bits(Vec<bool>),
}

impl Workers {
    /// A pool of `threads` host threads (at least 1).
    pub fn new(threads: usize) -> Workers {
        let threads = (0..threads.max(1))
            .map(|i| {
                let (tx, rx) = unbounded();
                std::thread::Builder::new()
                    .name(format!("pxpl5-renderer-{i}"))
                    .spawn(move || work(rx))
                    .expect("the host can start a worker thread");
                tx
            })
            .collect();
        Workers {
            threads,
            adopted: Cell::new(0),
        }
    }

    /// The pool's threads.
    pub fn threads(&self) -> usize {
        self.threads.len()
    }

    /// Take `pixels` onto the next thread; the handle the board keeps.
    pub(crate) fn adopt(&self, pixels: Box<Pixels>) -> Remote {
        let board = self.adopted.get();
        self.adopted.set(board + 1);
        let to = self.threads[board % self.threads.len()].clone();
        let (replies, from) = unbounded();
        send(
            &to,
            Job::Adopt {
                board,
                pixels,
                replies,
            },
        );
        Remote { board, to, from }
    }
}

/// Send `job`; a worker gone is a worker that panicked (a simulator bug, already reported on
/// stderr by the panic).
fn send(to: &Sender<Job>, job: Job) {
    to.send(job)
        .unwrap_or_else(|_| panic!("a Renderer worker thread has died (see its panic above)"));
}

/// A worker thread: its boards' pixels, and the jobs in order.
fn work(jobs: Receiver<Job>) {
    let mut boards: std::collections::BTreeMap<usize, (Box<Pixels>, Sender<Reply>)> =
        std::collections::BTreeMap::new();
    for job in jobs {
        match job {
            Job::Adopt {
                board,
                pixels,
                replies,
            } => {
                boards.insert(board, (pixels, replies));
            }
            Job::Apply { board, command } => {
                boards.get_mut(&board).expect("adopted").0.apply(&command);
            }
            Job::Ask { board, question } => {
                let (pixels, replies) = boards.get_mut(&board).expect("adopted");
                let reply = match question {
                    Question::Apply(c) => Reply::Readback(pixels.apply(&c)),
                    Question::Image => Reply::Image(pixels.image()),
                    Question::FieldValues(f) => Reply::Values(pixels.field_values(f)),
                    Question::BitValues(b) => Reply::Bits(pixels.bit_values(b)),
                };
                // The board may be gone already (dropped after asking): nothing to answer.
                let _ = replies.send(reply);
            }
            Job::Drop { board } => {
                boards.remove(&board);
            }
        }
    }
}

/// A board's handle on its pixels on a worker thread.
pub(crate) struct Remote {
    board: usize,
    to: Sender<Job>,
    from: Receiver<Reply>,
}

impl Remote {
    /// Apply `command`: at once for most commands, waiting for a readback's messages.
    pub(crate) fn apply(&mut self, command: &Command) -> Option<ReadbackStream> {
        if matches!(command, Command::Readback { .. }) {
            match self.ask(Question::Apply(command.clone())) {
                Reply::Readback(r) => r,
                _ => unreachable!("a readback is answered with its messages"),
            }
        } else {
            let board = self.board;
            let command = command.clone();
            send(&self.to, Job::Apply { board, command });
            None
        }
    }

    pub(crate) fn image(&self) -> BoardImage {
        match self.ask(Question::Image) {
            Reply::Image(i) => i,
            _ => unreachable!("an image is answered with an image"),
        }
    }

    pub(crate) fn field_values(&self, field: Field) -> Vec<u64> {
        match self.ask(Question::FieldValues(field)) {
            Reply::Values(v) => v,
            _ => unreachable!("values are answered with values"),
        }
    }

    pub(crate) fn bit_values(&self, b: Bit) -> Vec<bool> {
        match self.ask(Question::BitValues(b)) {
            Reply::Bits(v) => v,
            _ => unreachable!("bits are answered with bits"),
        }
    }

    /// Ask the worker, which answers once it has applied every command sent before.
    fn ask(&self, question: Question) -> Reply {
        let board = self.board;
        send(&self.to, Job::Ask { board, question });
        self.from
            .recv()
            .unwrap_or_else(|_| panic!("a Renderer worker thread has died (see its panic above)"))
    }
}

impl Drop for Remote {
    fn drop(&mut self) {
        // The worker may have ended already (its pool and boards gone): nothing to free then.
        let _ = self.to.send(Job::Drop { board: self.board });
    }
}
