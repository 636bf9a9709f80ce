//! Shared helpers of the integration tests: where the workspace is, a test's output directory
//! ([`OutDir`]), a writer to read back ([`SharedBytes`]), a fixed pseudo-random sequence
//! ([`xorshift`]), and what the fuzz targets share ([`fuzzing`]: case counts, seeds, inputs
//! mutated from the shipped files). The crates' tests take it as a dev-dependency.

use std::ffi::OsStr;
use std::ops::Deref;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

pub mod fuzzing;

/// The workspace root (this crate lives in `tests/`).
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// A test's output directory under the system's temporary directory, named by `prefix`, the
/// process and `name`, and empty at first. It is removed when the test passes and kept when it
/// fails (dropped while panicking), for a look at what the run wrote. Before, every run of the
/// suite left some 80 directories of pictures and traces behind.
#[derive(Debug)]
pub struct OutDir(PathBuf);

impl OutDir {
    pub fn new(prefix: &str, name: &str) -> OutDir {
        let d = std::env::temp_dir().join(format!("{prefix}-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        OutDir(d)
    }
}

impl Drop for OutDir {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

impl Deref for OutDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for OutDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<OsStr> for OutDir {
    fn as_ref(&self) -> &OsStr {
        self.0.as_os_str()
    }
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
