//! `cargo xtask <task>`: the project's tasks, in Rust so they run the same
//! on every machine.
//!
//! * `ci` — installs what is missing (rust targets and components via
//!   rustup), then runs every check: rustfmt, clippy `-D warnings` on the
//!   host and on both microcontroller targets (each math backend, with and
//!   without defmt), all tests, the cross builds of the core, rustdoc with
//!   `-D warnings`, and the default simulator scenario end to end.
//! * `bench` — criterion benchmark of one control tick (host).

use std::process::{Command, ExitCode};
use std::time::Instant;

/// Microcontroller targets the core must build for.
const TARGETS: [&str; 2] = ["thumbv7em-none-eabihf", "thumbv6m-none-eabi"];

fn main() -> ExitCode {
    let task = std::env::args().nth(1).unwrap_or_default();
    let result = match task.as_str() {
        "ci" => ci(),
        "bench" => cargo(&["bench", "-p", "host-tests", "--bench", "tick"], &[]),
        _ => {
            eprintln!("usage: cargo xtask <ci|bench>");
            return ExitCode::from(2);
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask {task}: {e}");
            ExitCode::FAILURE
        }
    }
}

type Result = std::result::Result<(), String>;

fn ci() -> Result {
    let started = Instant::now();
    install_prerequisites()?;

    step("rustfmt", || cargo(&["fmt", "--all", "--", "--check"], &[]))?;
    step("clippy (host, all targets)", || {
        cargo(
            &[
                "clippy",
                "--workspace",
                "--all-targets",
                "--",
                "-D",
                "warnings",
            ],
            &[],
        )
    })?;
    for target in TARGETS {
        for features in [
            &["--features", "defmt"][..],
            &["--no-default-features", "--features", "micromath"][..],
        ] {
            step(&format!("clippy core {target} {features:?}"), || {
                let mut args = vec!["clippy", "-p", "wmr-core", "--target", target];
                args.extend_from_slice(features);
                args.extend_from_slice(&["--", "-D", "warnings"]);
                cargo(&args, &[])
            })?;
        }
    }
    step("tests (workspace)", || {
        cargo(&["test", "--workspace", "--all-targets"], &[])
    })?;
    step("doc tests (core)", || {
        cargo(&["test", "-p", "wmr-core", "--doc"], &[])
    })?;
    for target in TARGETS {
        step(&format!("cross build core {target} (release)"), || {
            cargo(
                &["build", "-p", "wmr-core", "--release", "--target", target],
                &[],
            )
        })?;
    }
    step("rustdoc -D warnings (core)", || {
        cargo(
            &["doc", "-p", "wmr-core", "--no-deps"],
            &[("RUSTDOCFLAGS", "-D warnings")],
        )
    })?;
    step("default scenario end to end", || {
        cargo(
            &[
                "run",
                "--release",
                "-p",
                "firmware-sim",
                "--",
                "run",
                "--out",
                "target/ci/default-scenario",
            ],
            &[],
        )
    })?;
    eprintln!(
        "\nxtask ci: every check passed in {:.0} s",
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Rust targets and components the checks need, installed when missing.
fn install_prerequisites() -> Result {
    let installed = output("rustup", &["target", "list", "--installed"])?;
    let missing: Vec<&str> = TARGETS
        .iter()
        .copied()
        .filter(|t| !installed.lines().any(|l| l.trim() == *t))
        .collect();
    if !missing.is_empty() {
        let mut args = vec!["target", "add"];
        args.extend(&missing);
        run("rustup", &args, &[])?;
    }
    let components = output("rustup", &["component", "list", "--installed"])?;
    for component in ["rustfmt", "clippy"] {
        if !components.lines().any(|l| l.starts_with(component)) {
            run("rustup", &["component", "add", component], &[])?;
        }
    }
    Ok(())
}

fn step(name: &str, f: impl FnOnce() -> Result) -> Result {
    eprintln!("\n==> {name}");
    let started = Instant::now();
    f().map_err(|e| format!("{name}: {e}"))?;
    eprintln!("    {name}: ok ({:.1} s)", started.elapsed().as_secs_f64());
    Ok(())
}

fn cargo(args: &[&str], env: &[(&str, &str)]) -> Result {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    run(&cargo, args, env)
}

fn run(program: &str, args: &[&str], env: &[(&str, &str)]) -> Result {
    let status = Command::new(program)
        .args(args)
        .envs(env.iter().copied())
        .status()
        .map_err(|e| format!("cannot start {program}: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("`{program} {}` failed ({status})", args.join(" ")))
    }
}

fn output(program: &str, args: &[&str]) -> std::result::Result<String, String> {
    let out = Command::new(program)
        .args(args)
        .output()
        .map_err(|e| format!("cannot start {program}: {e}"))?;
    if out.status.success() {
        Ok(String::from_utf8_lossy(&out.stdout).into_owned())
    } else {
        Err(format!(
            "`{program} {}` failed ({})",
            args.join(" "),
            out.status
        ))
    }
}
