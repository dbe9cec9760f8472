//! What the end-to-end tests of the `acdf` command share: running the
//! binary with arguments, and with a standard input.

use std::io::Write;
use std::process::{Command, Output, Stdio};

/// Run `acdf` with `args`.
pub fn acdf(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_acdf"))
        .args(args)
        .output()
        .expect("the acdf binary runs")
}

/// Run `acdf` with `args` and `input` on its standard input.
pub fn acdf_stdin(args: &[&str], input: &str) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_acdf"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the acdf binary runs");
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    child.wait_with_output().unwrap()
}
