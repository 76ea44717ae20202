//! Building the firmware package for the microcontroller and running its
//! binaries under QEMU: shared by `bench-target`, `size` and `opt-levels`.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::thread;
use std::time::{Duration, Instant};

/// The firmware's target.
pub const TARGET: &str = "thumbv7em-none-eabihf";

/// QEMU's Arm system emulator (the firmware's `netduinoplus2` machine).
const QEMU: &str = "qemu-system-arm";

/// The workspace root (xtask's parent directory).
pub fn workspace_root() -> PathBuf {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    manifest.parent().unwrap_or(manifest).to_path_buf()
}

/// The Cortex-M0 bench's manifest: a workspace of its own (it links its own
/// `memory.x`; the root `Cargo.toml` says why).
pub const BENCH_M0_MANIFEST: &str = "firmware/bench-m0/Cargo.toml";

/// The cargo arguments that select `package`: `-p` for a package of this
/// workspace, `--manifest-path` for `wmr-bench-m0`, a workspace of its own
/// (whose own target directory would be `firmware/bench-m0/target`: callers
/// give it one inside this workspace's).
pub fn package_args(package: &str) -> [String; 2] {
    if package == "wmr-bench-m0" {
        let manifest = workspace_root().join(BENCH_M0_MANIFEST);
        [
            "--manifest-path".into(),
            manifest.to_string_lossy().into_owned(),
        ]
    } else {
        ["-p".into(), package.into()]
    }
}

/// xtask's own cargo target directory. Builds elsewhere in `target/` (other
/// tasks, an editor, a colleague's shell) cannot swap an ELF between its
/// build and its use here, and an opt-level override here invalidates
/// nothing there.
pub fn target_dir() -> PathBuf {
    workspace_root().join("target").join("xtask")
}

/// The Black Pill's build of the firmware crate for size: `--config` for
/// cargo, on every Black Pill build (`size`, `firmware`, `flash`,
/// `panic-free`; `host-tests/tests/robot_file.rs` gives the same). The
/// firmware crate alone (the board's set-up, its run loop, the robot
/// image's decoding and, monomorphised there, the core's generic robot) at
/// `opt-level = "z"`: a robot image with a route is 54,016 B at the
/// release profile's 3, over the board's 48 KiB, and 44,060 B so. The
/// rest (the core's pilot, estimators, laws and route follower, the
/// dependencies) keeps opt-level 3, and the dependencies are those of the
/// QEMU board's build, not compiled again. The QEMU board and the bench
/// (`bench-target`'s instruction counts) are built at 3.
pub const BLACKPILL_CONFIG: &str = "profile.release.package.wmr-firmware.opt-level=\"z\"";

/// The Black Pill's feature.
const BLACKPILL_FEATURE: &str = "board-blackpill";

/// One release build of `wmr-firmware` binaries.
#[derive(Debug, Clone, Copy, Default)]
pub struct Build<'a> {
    /// `--bin` names.
    pub bins: &'a [&'a str],
    /// `--no-default-features` (the default feature is `board-qemu`).
    pub no_default_features: bool,
    /// `--features`.
    pub features: &'a [&'a str],
    /// Extra environment (e.g. `CARGO_PROFILE_RELEASE_OPT_LEVEL`).
    pub env: &'a [(&'a str, &'a str)],
}

impl Build<'_> {
    /// Builds, then copies each ELF to `target/xtask/elf/<label>/<bin>`,
    /// where the next build (other features, other opt-level) leaves it be.
    /// Returns the copies, in the order of `bins`.
    pub fn run(&self, label: &str) -> Result<Vec<PathBuf>, String> {
        let features = self.features.join(",");
        let mut args = Vec::new();
        if self.features.contains(&BLACKPILL_FEATURE) {
            args.extend(["--config", BLACKPILL_CONFIG]);
        }
        for bin in self.bins {
            args.extend(["--bin", bin]);
        }
        if self.no_default_features {
            args.push("--no-default-features");
        }
        if !features.is_empty() {
            args.extend(["--features", &features]);
        }
        build_release("wmr-firmware", TARGET, &args, self.env, self.bins, label)
    }
}

/// `cargo build -p <package> --release --target <target>` with `args`
/// into xtask's target directory, then copies each of `bins` to
/// `target/xtask/elf/<label>/<bin>`, where the next build (other features,
/// other opt-level) leaves it be. Returns the copies, in the order of
/// `bins`.
pub fn build_release(
    package: &str,
    target: &str,
    args: &[&str],
    env: &[(&str, &str)],
    bins: &[&str],
    label: &str,
) -> Result<Vec<PathBuf>, String> {
    let dir = target_dir();
    let dir_arg = dir.to_string_lossy().into_owned();
    let selector = package_args(package);
    let mut all = vec!["build"];
    all.extend(selector.iter().map(String::as_str));
    all.extend(["--release", "--target", target, "--target-dir", &dir_arg]);
    all.extend(args);
    crate::cargo(&all, env)?;
    let out = dir.join("elf").join(label);
    std::fs::create_dir_all(&out).map_err(|e| format!("create {}: {e}", out.display()))?;
    bins.iter()
        .map(|bin| {
            let built = dir.join(target).join("release").join(bin);
            let copy = out.join(bin);
            std::fs::copy(&built, &copy)
                .map_err(|e| format!("copy {} to {}: {e}", built.display(), copy.display()))?;
            Ok(copy)
        })
        .collect()
}

/// Runs an ELF on QEMU's `netduinoplus2` with `-icount shift=0` (one
/// instruction per virtual nanosecond) and semihosting, and returns its
/// output. Fails if QEMU is missing, the program exits non-zero, or it
/// runs longer than `timeout`.
pub fn qemu(elf: &Path, timeout: Duration) -> Result<String, String> {
    qemu_on(elf, "netduinoplus2", 0, timeout)
}

/// [`qemu`] on another `machine` (`microbit`: the Cortex-M0), with
/// `-icount shift=<icount_shift>` (2^shift virtual ns per instruction).
pub fn qemu_on(
    elf: &Path,
    machine: &str,
    icount_shift: u32,
    timeout: Duration,
) -> Result<String, String> {
    let shift = format!("shift={icount_shift}");
    let mut child = Command::new(QEMU)
        .args([
            "-M",
            machine,
            "-icount",
            &shift,
            "-nographic",
            "-monitor",
            "none",
            "-semihosting-config",
            "enable=on,target=native",
            "-kernel",
        ])
        .arg(elf)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                format!(
                    "`{QEMU}` not found: install QEMU's Arm system emulator, 7.2 or \
                     later (Debian/Ubuntu: `apt-get install qemu-system-arm`)"
                )
            } else {
                format!("cannot start {QEMU}: {e}")
            }
        })?;
    let drain = |pipe: Option<Box<dyn Read + Send>>| {
        thread::spawn(move || {
            let mut bytes = Vec::new();
            if let Some(mut pipe) = pipe {
                // A read error ends the capture; what was read is kept.
                let _ = pipe.read_to_end(&mut bytes);
            }
            String::from_utf8_lossy(&bytes).into_owned()
        })
    };
    let stdout = drain(child.stdout.take().map(|p| Box::new(p) as _));
    let stderr = drain(child.stderr.take().map(|p| Box::new(p) as _));
    let started = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break Ok(status),
            Ok(None) if started.elapsed() > timeout => {
                // Best effort: the child may have exited just now.
                let _ = child.kill();
                let _ = child.wait();
                break Err(format!(
                    "{} did not finish within {} s under {QEMU}",
                    elf.display(),
                    timeout.as_secs()
                ));
            }
            Ok(None) => thread::sleep(Duration::from_millis(20)),
            Err(e) => break Err(format!("waiting for {QEMU}: {e}")),
        }
    };
    let out = stdout.join().unwrap_or_default();
    let err = stderr.join().unwrap_or_default();
    match status {
        Ok(status) if status.success() => Ok(out),
        Ok(status) => Err(format!(
            "{} failed under {QEMU} ({status}):\n{out}{err}",
            elf.display()
        )),
        Err(e) => Err(format!("{e}:\n{out}{err}")),
    }
}

/// QEMU's version (`7.2.22`), for the reports.
pub fn qemu_version() -> String {
    crate::output(QEMU, &["--version"])
        .ok()
        .and_then(|v| {
            let line = v.lines().next()?;
            let version = line.split("version ").nth(1)?.split_whitespace().next()?;
            Some(format!("QEMU {version}"))
        })
        .unwrap_or_else(|| "QEMU".into())
}

/// `rustc --version`, for the reports.
pub fn rustc_version() -> String {
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    crate::output(&rustc, &["--version"])
        .map(|v| v.trim().to_string())
        .unwrap_or_else(|_| "rustc (version unknown)".into())
}

/// Writes `text` to `path` (under the workspace root), creating its folder.
pub fn write_report(path: &str, text: &str) -> Result<PathBuf, String> {
    let path = workspace_root().join(path);
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("create {}: {e}", dir.display()))?;
    }
    std::fs::write(&path, text).map_err(|e| format!("write {}: {e}", path.display()))?;
    Ok(path)
}

/// The text between the `start` and `end` markers of `path` (relative to
/// the workspace root), without the newline that follows `start`; `None`
/// if the file or either marker is missing.
pub fn marked_section(path: &str, start: &str, end: &str) -> Option<String> {
    let text = std::fs::read_to_string(workspace_root().join(path)).ok()?;
    let (body_start, body_end) = marker_span(&text, start, end).ok()?;
    Some(text[body_start..body_end].to_string())
}

/// Replaces what lies between the `start` and `end` markers of `path`
/// (relative to the workspace root, a tracked file) with `body`. Only for
/// an explicit request (`bench-target --write`): fails if the file or a
/// marker is missing, so that nothing is silently left stale.
pub fn update_marked(path: &str, start: &str, end: &str, body: &str) -> Result<PathBuf, String> {
    let full = workspace_root().join(path);
    let text =
        std::fs::read_to_string(&full).map_err(|e| format!("read {}: {e}", full.display()))?;
    let (body_start, body_end) =
        marker_span(&text, start, end).map_err(|e| format!("{}: {e}", full.display()))?;
    let updated = format!("{}{body}{}", &text[..body_start], &text[body_end..]);
    if updated != text {
        std::fs::write(&full, updated).map_err(|e| format!("write {}: {e}", full.display()))?;
    }
    Ok(full)
}

/// Byte range of the body between `start` (and the newline after it) and
/// `end`.
fn marker_span(text: &str, start: &str, end: &str) -> Result<(usize, usize), String> {
    let s = text
        .find(start)
        .ok_or_else(|| format!("no `{start}` marker"))?;
    let after_start = s + start.len();
    let body_start = after_start + usize::from(text[after_start..].starts_with('\n'));
    let body_end = text[body_start..]
        .find(end)
        .map(|e| e + body_start)
        .ok_or_else(|| format!("`{start}` but no `{end}` after it"))?;
    Ok((body_start, body_end))
}

/// `1234567` → `1 234 567` (thin-space-free, for markdown tables).
pub fn grouped(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(' ');
        }
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::{grouped, marker_span};

    #[test]
    fn finds_the_marked_body() {
        let text = "intro\n<!-- a -->\nold\nbody\n<!-- b -->\noutro\n";
        let (s, e) = marker_span(text, "<!-- a -->", "<!-- b -->").unwrap();
        assert_eq!(&text[s..e], "old\nbody\n");
        assert!(marker_span(text, "<!-- b -->", "<!-- a -->").is_err());
        assert!(marker_span(text, "<!-- c -->", "<!-- b -->").is_err());
    }

    #[test]
    fn groups_thousands() {
        assert_eq!(grouped(0), "0");
        assert_eq!(grouped(999), "999");
        assert_eq!(grouped(1000), "1 000");
        assert_eq!(grouped(1_234_567), "1 234 567");
    }

    /// The host test that builds the Black Pill with a robot image gives
    /// cargo the same configuration as xtask's Black Pill builds.
    #[test]
    fn the_robot_file_test_builds_the_blackpill_as_xtask_does() {
        let test =
            std::fs::read_to_string(super::workspace_root().join("host-tests/tests/robot_file.rs"))
                .unwrap();
        let quoted = format!("{:?}", super::BLACKPILL_CONFIG);
        assert!(
            test.contains(&format!("const BLACKPILL_CONFIG: &str = {quoted};")),
            "host-tests/tests/robot_file.rs: BLACKPILL_CONFIG is not {quoted}"
        );
    }
}
