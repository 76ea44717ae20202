//! What the command-line tests share.

use std::process::{Command, Output};

/// The built `firmware-sim` binary.
pub fn sim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_firmware-sim"))
}

/// The standard output of a run that must have succeeded (the assertion
/// shows its standard error otherwise).
pub fn stdout_of_success(out: &Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}
