//! The Slurm scripts (`scripts/slurm/`) on a one-node Slurm that `test-one-node.sh` installs and
//! starts itself: a study run as a job array of shards and merged equals one run's bytes.
//! Opt-in, as it installs packages and starts daemons: `PXPL5_SLURM_TEST=1` runs it (about ten
//! seconds once slurm-wlm and munge are installed); without it the test passes at once.

use std::path::PathBuf;
use std::process::Command;

#[test]
fn a_slurm_array_merges_to_one_runs_bytes() {
    if std::env::var_os("PXPL5_SLURM_TEST").is_none_or(|v| v != "1") {
        eprintln!("skipped: set PXPL5_SLURM_TEST=1 to run the Slurm scripts on a one-node Slurm");
        return;
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let out = Command::new(root.join("scripts/slurm/test-one-node.sh"))
        .arg(env!("CARGO_BIN_EXE_pxpl5"))
        .output()
        .expect("the script runs");
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{stdout}\n{stderr}");
    assert!(stdout.contains("equal one run's bytes"), "{stdout}");
}
