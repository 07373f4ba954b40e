//! The `ratf` binary as a user runs it: piped into a reader that stops early.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

/// `ratf sim | head -1`: once the reader is gone the program ends quietly (exit 0, nothing
/// on stderr) instead of panicking on the broken pipe.
#[test]
fn a_reader_that_stops_early_ends_the_program_quietly() {
    let out_dir = std::env::temp_dir().join(format!("ratf-cli-test-{}", std::process::id()));
    let mut child = Command::new(env!("CARGO_BIN_EXE_ratf"))
        .args(["sim", "--round", "1", "--out"])
        .arg(&out_dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ratf starts");
    let stdout = child.stdout.take().expect("piped stdout");
    let mut first = String::new();
    BufReader::new(stdout)
        .read_line(&mut first)
        .expect("one line");
    assert!(first.starts_with("ratf sim: round 1"), "{first}");
    // The reader goes away here, like `head -1`.
    let output = child.wait_with_output().expect("ratf ends");
    let _ = std::fs::remove_dir_all(&out_dir);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{:?}: {stderr}", output.status);
    assert!(!stderr.contains("panicked"), "{stderr}");
}
