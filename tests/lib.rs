//! Shared helpers of the integration tests: where the workspace is, a writer to read back
//! ([`SharedBytes`]), a fixed pseudo-random sequence ([`xorshift`]), and what the fuzz targets share ([`fuzzing`]: case counts, seeds, inputs
//! mutated from the shipped files). The crates' tests take it as a dev-dependency.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

pub mod fuzzing;

/// The workspace root (this crate lives in `tests/`).
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// An in-memory writer whose bytes a test reads back after handing a clone away as a
/// `Box<dyn Write + Send>` (a streamed trace keeps its writer to the end).
#[derive(Clone, Debug, Default)]
pub struct SharedBytes(Arc<Mutex<Vec<u8>>>);

impl SharedBytes {
    /// The bytes written so far, through every clone.
    pub fn bytes(&self) -> Vec<u8> {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }
}

impl std::io::Write for SharedBytes {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// A fixed pseudo-random sequence from `seed` (xorshift64; a nonzero seed): for tests that want
/// many varied inputs and the same ones every run. Its low bits vary as much as its high ones,
/// unlike an LCG's, so `next() % k` is fine.
pub fn xorshift(seed: u64) -> impl FnMut() -> u64 {
    let mut state = seed;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    }
}
