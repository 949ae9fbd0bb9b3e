//! Helpers shared by the app's end-to-end tests: run the binary, scratch
//! files, and the checks for success and for a clean error exit.

// Each test module uses a different subset of these.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Run `rtsim` with `args`.
pub fn rtsim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rtsim"))
        .args(args)
        .output()
        .expect("rtsim runs")
}

/// A scratch path, in a folder of the calling test file and this process
/// (the test files share one binary, so their names may repeat).
#[track_caller]
pub fn tmp(name: &str) -> PathBuf {
    let file = std::panic::Location::caller().file();
    let stem = Path::new(file).file_stem().and_then(|s| s.to_str());
    let d = std::env::temp_dir().join(format!(
        "rtsim-{}-{}-{}",
        env!("CARGO_CRATE_NAME"),
        stem.unwrap_or("test"),
        std::process::id()
    ));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// Assert success; the standard output.
pub fn ok(o: &Output) -> String {
    assert!(
        o.status.success(),
        "exit {:?}\nstdout: {}\nstderr: {}",
        o.status.code(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout.clone()).unwrap()
}

/// Assert exit code 2 without a panic; the standard error.
pub fn err(o: &Output) -> String {
    assert_eq!(
        o.status.code(),
        Some(2),
        "stdout: {}",
        String::from_utf8_lossy(&o.stdout)
    );
    let e = String::from_utf8(o.stderr.clone()).unwrap();
    assert!(!e.contains("panicked"), "no panic: {e}");
    e
}

/// Assert success and parse the standard output as JSON.
pub fn json(o: &Output) -> serde_json::Value {
    serde_json::from_str(&ok(o)).unwrap()
}
