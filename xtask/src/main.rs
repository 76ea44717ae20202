//! `cargo xtask <task>`: the project's tasks, in Rust so they run the same
//! on every machine.
//!
//! * `ci` — installs what is missing (rust targets and components via
//!   rustup, `qemu-system-arm` via apt-get, the firmware's linker
//!   flip-link and cargo-fuzz via `cargo install`; the nightly toolchain
//!   of the fuzz targets must be there already, and CI fails at once,
//!   saying so, without it), then runs every check:
//!   rustfmt, clippy `-D warnings` on the host and on the microcontroller
//!   targets (the feature matrix of `features`, and the link), the cross
//!   builds, all tests (the hardware-in-the-loop tests run the QEMU-board
//!   firmware; a pymavlink ground station, installed into a Python
//!   virtual environment, checks the MAVLink SITL: `gcs`), the core's
//!   tests again with its default features alone, rustdoc with `-D warnings`, the default simulator scenario end to end,
//!   and the on-target gates `size` and `bench-target`, which fail on a
//!   figure over its budget in `firmware/budgets.toml` (or a software
//!   `f64` routine in the firmware), the link-time proof that the firmware
//!   cannot panic (`panic-free`), and every fuzz target for a short time
//!   (`fuzz`). It never writes a tracked file: its reports go to `target/`.
//! * `features` — clippy `-D warnings` on the feature matrix alone: the
//!   core on both microcontroller targets and the firmware with each
//!   board, for a covering set of the feature combinations a user can
//!   pick (the table and why these rows: `xtask/src/features.rs`).
//! * `firmware` — release ELFs of both boards, copied to
//!   `target/firmware/wmr-firmware-<board>.elf`. `firmware --robot FILE`:
//!   the Black Pill firmware with that robot file's configuration in flash
//!   (`xtask/src/robot.rs`); `flash --robot FILE` also flashes it with
//!   probe-rs.
//! * `panic-free` — the link-time proof that the release firmware cannot
//!   panic: each board, in its default configuration and with each
//!   estimator feature, built with a panic handler that cannot link while
//!   any panic path remains (`xtask/src/panic_free.rs`, docs/firmware.md).
//! * `bench` — criterion benchmark of one control tick (host).
//! * `bench-target [--write]` — instructions per call of the tick and its
//!   stages on the target (QEMU `netduinoplus2`, `-icount shift=0`), for
//!   each math backend; writes `target/bench-target.md`, and with
//!   `--write` also the generated section of `docs/budgets.md` (between
//!   its `bench-target` markers), the only task that writes a tracked file;
//!   fails when the default backend's instructions or tick stack exceed
//!   their budgets (`firmware/budgets.toml`, `xtask/src/budgets.rs`).
//! * `size` — flash and static RAM of the release firmware (each board
//!   that builds) and its biggest symbols; writes `target/size.md`; fails
//!   on a flash budget or limit exceeded, or a software `f64` routine.
//! * `fuzz [--seconds N]` — every fuzz target of `fuzz/` (cargo-fuzz, on the
//!   nightly toolchain, which must be installed: it fails saying so if
//!   not) for N seconds each (default 15) on its committed corpus; installs
//!   cargo-fuzz with cargo when missing; fails on any crash
//!   (`xtask/src/fuzz.rs`).
//! * `opt-levels` — firmware size and tick instructions for each release
//!   opt-level (3, 2, s, z); writes `target/opt-levels.md`. Slow: every
//!   level rebuilds all dependencies.
//! * `gcs [--hil [--particle-filter]]` — the pymavlink ground station
//!   (`tools/gcs/gcs_check.py`) against `firmware-sim sitl` (release), or
//!   with `--hil` against the firmware under QEMU (`firmware-sim hil
//!   --mavlink`; `--particle-filter`: the firmware built with the fusion
//!   particle filter, on the route with that filter), in a Python
//!   virtual environment under `target/gcs-venv` with the pinned
//!   `tools/gcs/requirements.txt` (`xtask/src/gcs.rs`); `ci` runs the same
//!   script both ways from the workspace tests
//!   (`firmware-sim/tests/sitl.rs`, `firmware-sim/tests/hil_mavlink.rs`).

mod bench_target;
mod budgets;
mod features;
mod fuzz;
mod gcs;
mod opt_levels;
mod panic_free;
mod robot;
mod size;
mod target;

use std::process::{Command, ExitCode};
use std::time::Instant;

/// Microcontroller targets the core must build for.
const TARGETS: [&str; 2] = ["thumbv7em-none-eabihf", "thumbv6m-none-eabi"];

/// The command line's synopsis.
const USAGE: &str = "usage: cargo xtask <ci|features|firmware [--robot FILE]|flash --robot FILE|panic-free|bench|bench-target [--write]|size|opt-levels|fuzz [--seconds N]|gcs [--hil [--particle-filter]]>";

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let task = args.next().unwrap_or_default();
    let options: Vec<String> = args.collect();
    let mut write = false;
    let mut fuzz_seconds = fuzz::CI_SECONDS;
    let mut robot = None;
    let mut gcs_hil = None;
    match (task.as_str(), options.as_slice()) {
        ("gcs", [flag]) if flag == "--hil" => gcs_hil = Some(gcs::HilFirmware::Default),
        ("gcs", [flag, pf]) if flag == "--hil" && pf == "--particle-filter" => {
            gcs_hil = Some(gcs::HilFirmware::ParticleFilter);
        }
        ("bench-target", [flag]) if flag == "--write" => write = true,
        ("firmware" | "flash", [flag, file]) if flag == "--robot" => robot = Some(file.clone()),
        ("flash", _) => {
            eprintln!("{USAGE}");
            return ExitCode::from(2);
        }
        ("fuzz", [flag, n]) if flag == "--seconds" => match n.parse() {
            Ok(n) if n > 0 => fuzz_seconds = n,
            _ => {
                eprintln!("{USAGE}");
                return ExitCode::from(2);
            }
        },
        (_, []) => {}
        _ => {
            eprintln!("{USAGE}");
            return ExitCode::from(2);
        }
    }
    let result = match task.as_str() {
        "ci" => ci(),
        "features" => features::clippy_matrix(),
        "firmware" => match &robot {
            Some(file) => robot::build_robot_firmware(file).map(|elf| {
                println!("blackpill  {}", elf.display());
            }),
            None => build_firmware().map(|elfs| {
                for (board, elf) in elfs {
                    println!("{board:<10} {}", elf.display());
                }
            }),
        },
        "flash" => robot
            .as_deref()
            .map_or_else(|| Err(USAGE.to_owned()), robot::flash),
        "panic-free" => panic_free::panic_free(),
        "bench" => cargo(&["bench", "-p", "host-tests", "--bench", "tick"], &[]),
        "bench-target" => bench_target::bench_target(write),
        "size" => size::size(),
        "opt-levels" => opt_levels::opt_levels(),
        "fuzz" => fuzz::fuzz(fuzz_seconds),
        "gcs" => gcs::gcs(gcs_hil),
        _ => {
            eprintln!("{USAGE}");
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
    // The core on both targets and the firmware with each board, for the
    // feature combinations of `features.rs`.
    features::clippy_matrix()?;
    step("clippy link thumbv7em-none-eabihf", || {
        cargo(
            &[
                "clippy",
                "-p",
                "wmr-link",
                "--target",
                FIRMWARE_TARGET,
                "--",
                "-D",
                "warnings",
            ],
            &[],
        )
    })?;
    let elfs = build_firmware()?;
    let qemu_elf = elfs
        .iter()
        .find(|(board, _)| *board == "qemu")
        .map(|(_, elf)| elf.display().to_string())
        .ok_or("no QEMU-board firmware")?;
    let variants = build_hil_variants()?;
    // The robot-file test builds the Black Pill firmware with a robot's
    // image into xtask's target directory too (only the firmware crate is
    // compiled again).
    let firmware_target_dir = target::target_dir().display().to_string();
    // The pymavlink ground station of firmware-sim/tests/sitl.rs (run
    // against the SITL by the workspace tests): its Python environment.
    let gcs_python = gcs::venv()?.display().to_string();
    let mut test_env = vec![
        ("WMR_GCS_PYTHON", gcs_python.as_str()),
        ("WMR_FIRMWARE_ELF", qemu_elf.as_str()),
        ("WMR_FIRMWARE_TARGET_DIR", firmware_target_dir.as_str()),
    ];
    test_env.extend(variants.iter().map(|(var, elf)| (*var, elf.as_str())));
    step("tests (workspace, HIL under QEMU)", || {
        cargo(&["test", "--workspace", "--all-targets"], &test_env)
    })?;
    // The workspace test run unifies features (the simulator and the tests
    // turn every core feature on), so the core's default-feature paths
    // (the f32 backend, no estimator feature) are tested here, doc tests
    // included.
    step("tests (core, default features alone)", || {
        cargo(&["test", "-p", "wmr-core"], &[])
    })?;
    for target in TARGETS {
        step(
            &format!("cross build core, papers {target} (release)"),
            || {
                cargo(
                    &[
                        "build",
                        "-p",
                        "wmr-core",
                        "-p",
                        "wmr-papers",
                        "--release",
                        "--target",
                        target,
                    ],
                    &[],
                )
            },
        )?;
    }
    step("rustdoc -D warnings (core, papers, link)", || {
        cargo(
            &[
                "doc",
                "-p",
                "wmr-core",
                "-p",
                "wmr-papers",
                "-p",
                "wmr-link",
                "--no-deps",
            ],
            &[("RUSTDOCFLAGS", "-D warnings")],
        )
    })?;
    // The tools' docs are read by the people who extend them: their
    // private items too.
    step(
        "rustdoc -D warnings (firmware-sim, host-tests, xtask; private items)",
        || {
            cargo(
                &[
                    "doc",
                    "-p",
                    "firmware-sim",
                    "-p",
                    "host-tests",
                    "-p",
                    "xtask",
                    "--no-deps",
                    "--document-private-items",
                ],
                &[("RUSTDOCFLAGS", "-D warnings")],
            )
        },
    )?;
    // Gates: a figure over its budget in firmware/budgets.toml fails CI.
    step("size (budgets)", size::size)?;
    step("bench-target (budgets)", || {
        bench_target::bench_target(false)
    })?;
    // The firmware cannot panic: every board and estimator feature links
    // with a panic handler that cannot link while a panic path remains.
    step("panic-free (link-time proof)", panic_free::panic_free)?;
    // Each fuzz target for a short time on its committed corpus (the long
    // runs are done by hand: fuzz/README.md).
    fuzz::fuzz(fuzz::CI_SECONDS)?;
    eprintln!(
        "\nxtask ci: every check passed in {:.0} s",
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The firmware's target.
const FIRMWARE_TARGET: &str = "thumbv7em-none-eabihf";

/// Firmware boards and the cargo feature that selects each.
const BOARDS: [(&str, &str); 2] = [("qemu", "board-qemu"), ("blackpill", "board-blackpill")];

/// Builds the release firmware of each board (into xtask's own target
/// directory, shared with `size` and `bench-target`) and copies each ELF to
/// `target/firmware/wmr-firmware-<board>.elf`.
fn build_firmware() -> std::result::Result<Vec<(&'static str, std::path::PathBuf)>, String> {
    let out_dir = target::workspace_root().join("target").join("firmware");
    std::fs::create_dir_all(&out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    let mut elfs = Vec::new();
    for (board, feature) in BOARDS {
        let mut built = Vec::new();
        step(&format!("build firmware {board} (release)"), || {
            built = target::Build {
                bins: &["wmr-firmware"],
                no_default_features: true,
                features: &[feature],
                env: &[],
            }
            .run(&format!("firmware-{board}"))?;
            Ok(())
        })?;
        let built = built.first().ok_or("no ELF built")?;
        let elf = out_dir.join(format!("wmr-firmware-{board}.elf"));
        std::fs::copy(built, &elf).map_err(|e| format!("{}: {e}", built.display()))?;
        elfs.push((board, elf));
    }
    Ok(elfs)
}

/// Builds the QEMU-board firmware of each optional build
/// ([`wmr_core::builds::OPTIONAL_BUILDS`]: the fusion estimator's UKF and
/// particle filter, the wheel-speed observer), for the HIL tests beside
/// the default one, copied to `target/firmware/wmr-firmware-qemu-<feature>.elf`;
/// returns the environment variable that gives the tests each ELF, and its
/// path. Built here, in xtask's target directory whose dependencies the
/// default build compiled, rather than by the tests, each in a target
/// directory of its own from scratch. Each is a build of its own, as a
/// robot would carry it (the flash budget leaves no room for all at once:
/// docs/budgets.md, "Flash and static RAM"; and the particle filter's
/// frames would set the others' stack).
fn build_hil_variants() -> std::result::Result<Vec<(&'static str, String)>, String> {
    wmr_core::builds::OPTIONAL_BUILDS
        .into_iter()
        .map(|build| {
            let elf = build_hil_variant(build)?;
            Ok((build.hil_firmware_env, elf.display().to_string()))
        })
        .collect()
}

/// The QEMU-board firmware of one optional build, as
/// [`build_hil_variants`] builds each: its ELF's copy.
fn build_hil_variant(
    build: wmr_core::builds::OptionalBuild,
) -> std::result::Result<std::path::PathBuf, String> {
    let label = format!("qemu-{}", build.feature);
    let features = &["board-qemu", build.feature];
    let mut built = Vec::new();
    step(
        &format!("build firmware {} (release)", features.join(" + ")),
        || {
            built = target::Build {
                bins: &["wmr-firmware"],
                no_default_features: true,
                features,
                env: &[],
            }
            .run(&format!("firmware-{label}"))?;
            Ok(())
        },
    )?;
    let built = built.first().ok_or("no ELF built")?;
    let out_dir = target::workspace_root().join("target").join("firmware");
    std::fs::create_dir_all(&out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    let elf = out_dir.join(format!("wmr-firmware-{label}.elf"));
    std::fs::copy(built, &elf).map_err(|e| format!("{}: {e}", built.display()))?;
    Ok(elf)
}

/// flip-link, the firmware's linker (`.cargo/config.toml`), installed with
/// cargo when missing.
fn install_flip_link() -> Result {
    match Command::new("flip-link").output() {
        Ok(_) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            eprintln!("flip-link missing: installing it with cargo");
            cargo(&["install", "flip-link", "--locked"], &[])
        }
        Err(e) => Err(format!("cannot start flip-link: {e}")),
    }
}

/// `qemu-system-arm` for the hardware-in-the-loop tests, installed with
/// apt-get when missing (with sudo when not root).
fn install_qemu() -> Result {
    if output("qemu-system-arm", &["--version"]).is_ok() {
        return Ok(());
    }
    eprintln!("qemu-system-arm missing: installing it with apt-get");
    let root = output("id", &["-u"]).is_ok_and(|uid| uid.trim() == "0");
    let apt = |args: &[&str]| {
        if root {
            run("apt-get", args, &[("DEBIAN_FRONTEND", "noninteractive")])
        } else {
            let mut with_sudo = vec!["apt-get"];
            with_sudo.extend_from_slice(args);
            run("sudo", &with_sudo, &[("DEBIAN_FRONTEND", "noninteractive")])
        }
    };
    apt(&["update", "-q"])?;
    apt(&[
        "install",
        "-y",
        "-q",
        "--no-install-recommends",
        "qemu-system-arm",
    ])?;
    output("qemu-system-arm", &["--version"]).map(|_| ())
}

/// Rust targets and components the checks need, installed when missing;
/// the nightly toolchain of the fuzz targets, checked (not installed: CI
/// fails, saying so, without it); cargo-fuzz, installed when missing.
fn install_prerequisites() -> Result {
    // First, so that a machine without nightly fails at once, not after
    // every other check.
    fuzz::prerequisites()?;
    install_qemu()?;
    install_flip_link()?;
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
