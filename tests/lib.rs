//! Shared helpers of the integration tests: where the workspace is, and what the fuzz targets
//! share ([`fuzzing`]: case counts, seeds, inputs mutated from the shipped files). The crates'
//! tests take it as a dev-dependency.

use std::path::PathBuf;

pub mod fuzzing;

/// The workspace root (this crate lives in `tests/`).
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}
