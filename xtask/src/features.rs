//! The feature matrix: the feature combinations `cargo xtask ci` lints
//! (`cargo xtask features` runs only them), in one place.
//!
//! A user picks, for the core: a math backend (none: the `f32`-native
//! default; `libm`, `micromath` or both, where `micromath` wins), an
//! estimator (none: paper 001's observer and
//! paper 002's; `fusion-ekf`; `fusion-ukf` or `fusion-particle-filter`,
//! each of which implies `fusion-ekf`; or all), `wheel-speed-observer`,
//! `defmt` and `serde`. The power set is 4 × 5 × 2³ = 160 builds per
//! target, about 2 s each once the dependencies are built. The lints a
//! `cfg` hides (unused imports, dead code, a missing derive) almost always
//! come from one feature being on or off, so a covering set is enough:
//! every feature is built on in one row and off in another, each math
//! backend alone and both together, and each estimator feature alone,
//! including no estimator at all (the `not(feature = "fusion-ekf")` paths,
//! which the workspace build, where the simulator turns every feature on,
//! never compiles). The last row turns everything on. `std`, `schemars`
//! and `arbitrary` are for host tools (`schemars` does not even build for
//! the Cortex-M0, which lacks pointer atomics; `arbitrary` needs `std`):
//! the host clippy of the workspace turns them all on at once, and
//! [`CORE_HOST`] builds each of them without the others on the host.
//!
//! The firmware always takes the core with `defmt` (and `serde` through
//! the link), so its choices are a board, the math backend (`micromath`,
//! or `libm` for comparison) and the estimator and `wheel-speed-observer`
//! features; each row runs with each board.
//!
//! The tests below check these properties against `core/Cargo.toml` and
//! `firmware/Cargo.toml`, so a new feature that the matrix misses fails
//! `cargo test -p xtask`.

/// The core's rows, each its whole feature set (built with
/// `--no-default-features`), linted on each of [`crate::TARGETS`].
pub const CORE: [&[&str]; 6] = [
    // The default build (the f32 backend), no estimator feature: paper
    // 001 and 002 only.
    &[],
    // The other backend alone, no estimator feature.
    &["micromath"],
    // The fusion EKF alone, with serde.
    &["micromath", "serde", "fusion-ekf"],
    // The fusion UKF alone (implies the EKF), with defmt.
    &["libm", "defmt", "fusion-ukf"],
    // The particle filter alone (implies the EKF), both backends, the
    // wheel-speed observer.
    &[
        "libm",
        "micromath",
        "fusion-particle-filter",
        "wheel-speed-observer",
    ],
    // Everything.
    &[
        "libm",
        "micromath",
        "defmt",
        "serde",
        "fusion-ukf",
        "fusion-particle-filter",
        "wheel-speed-observer",
    ],
];

/// The core's host-tool rows (built with `--no-default-features` for the
/// host): what a host tool may turn on alone, which the workspace build,
/// turning everything on, never compiles by itself (`serde` with `std`
/// needs serde's own `std` for the files' tagged tables).
pub const CORE_HOST: [&[&str]; 4] = [&["std"], &["serde", "std"], &["schemars"], &["arbitrary"]];

/// The rows of `wmr-papers` (the papers' algorithms no robot runs; built
/// with `--no-default-features`), linted on each of [`crate::TARGETS`]:
/// each math backend of the core it calls, `defmt` and `serde` on and off.
pub const PAPERS: [&[&str]; 3] = [&[], &["libm"], &["micromath", "defmt", "serde"]];

/// The firmware's rows (built with `--no-default-features` and the board's
/// feature added), linted with each board of [`crate::BOARDS`].
pub const FIRMWARE: [&[&str]; 4] = [
    // The shipped configuration: the f32 backend, paper 001 and 002 and the
    // fusion EKF (every board turns `fusion-ekf` on).
    &[],
    // `bench-route-tick` is the on-target bench's route-tick build (`cargo
    // xtask bench-target`), linted here so that its `cfg` is.
    &["micromath", "bench-route-tick"],
    &["libm", "fusion-ukf", "wheel-speed-observer"],
    &["micromath", "fusion-particle-filter"],
];

/// The rows of `wmr-bench-m0` (the on-target bench for the Cortex-M0,
/// linted on `thumbv6m-none-eabi` only): its default backend, and both
/// other backends at once.
pub const BENCH_M0: [&[&str]; 2] = [
    &[],
    &["libm", "micromath", "fusion-ekf", "fusion-particle-filter"],
];

/// Clippy `-D warnings` on every row of the matrix.
pub fn clippy_matrix() -> crate::Result {
    let libraries: [(&str, &[&[&str]]); 2] = [("core", &CORE), ("papers", &PAPERS)];
    for target in crate::TARGETS {
        for (name, rows) in libraries {
            for row in rows {
                let features = row.join(",");
                let package = format!("wmr-{name}");
                clippy(
                    &format!("{name} {target} [{features}]"),
                    &package,
                    target,
                    &["--no-default-features", "--features", &features],
                )?;
            }
        }
    }
    for row in CORE_HOST {
        let features = row.join(",");
        crate::step(&format!("clippy core host [{features}]"), || {
            crate::cargo(
                &[
                    "clippy",
                    "-p",
                    "wmr-core",
                    "--all-targets",
                    "--no-default-features",
                    "--features",
                    &features,
                    "--",
                    "-D",
                    "warnings",
                ],
                &[],
            )
        })?;
    }
    for (board, board_feature) in crate::BOARDS {
        for row in FIRMWARE {
            let features = std::iter::once(board_feature)
                .chain(row.iter().copied())
                .collect::<Vec<_>>()
                .join(",");
            clippy(
                &format!("firmware {board} [{features}]"),
                "wmr-firmware",
                crate::FIRMWARE_TARGET,
                &[
                    "--release",
                    "--all-targets",
                    "--no-default-features",
                    "--features",
                    &features,
                ],
            )?;
        }
    }
    // The root workspace's `cargo fmt --all` does not reach the M0 bench's
    // own workspace (its binary is the firmware's bench source, formatted
    // there; this checks its build script).
    crate::step("rustfmt bench-m0", || {
        let manifest = crate::target::workspace_root().join(crate::target::BENCH_M0_MANIFEST);
        let manifest = manifest.to_string_lossy();
        crate::cargo(&["fmt", "--manifest-path", &manifest, "--", "--check"], &[])
    })?;
    for row in BENCH_M0 {
        let features = row.join(",");
        let target = crate::bench_target::M0_TARGET;
        clippy(
            &format!("bench-m0 {target} [{features}]"),
            "wmr-bench-m0",
            target,
            &["--release", "--all-targets", "--features", &features],
        )?;
    }
    Ok(())
}

/// One step of the matrix: `cargo clippy -p <package> --target <target>
/// <args> -- -D warnings` (`--manifest-path` for a workspace of its own:
/// [`crate::target::package_args`]), named `clippy <label>`.
fn clippy(label: &str, package: &str, target: &str, args: &[&str]) -> crate::Result {
    crate::step(&format!("clippy {label}"), || {
        let selector = crate::target::package_args(package);
        let mut all = vec!["clippy"];
        all.extend(selector.iter().map(String::as_str));
        all.extend(["--target", target]);
        let own_target_dir = crate::target::workspace_root()
            .join("target")
            .join("bench-m0")
            .to_string_lossy()
            .into_owned();
        if package == "wmr-bench-m0" {
            all.extend(["--target-dir", &own_target_dir]);
        }
        all.extend(args);
        all.extend(["--", "-D", "warnings"]);
        crate::cargo(&all, &[])
    })
}

#[cfg(test)]
mod tests {
    use super::{CORE, FIRMWARE};
    use std::collections::{BTreeMap, BTreeSet};

    /// A manifest's `[features]`: each feature and the features of the same
    /// package it turns on (entries with `dep:` or `/` are left out).
    fn features(manifest: &str) -> BTreeMap<String, Vec<String>> {
        let path = crate::target::workspace_root().join(manifest);
        let text = std::fs::read_to_string(&path).unwrap();
        let mut in_features = false;
        let mut out = BTreeMap::new();
        for line in text.lines().map(str::trim) {
            if line.starts_with('[') {
                in_features = line == "[features]";
                continue;
            }
            if !in_features || line.starts_with('#') || line.is_empty() {
                continue;
            }
            let (name, list) = line.split_once('=').unwrap();
            let implied = list
                .trim()
                .trim_start_matches('[')
                .trim_end_matches(']')
                .split(',')
                .map(|f| f.trim().trim_matches('"'))
                .filter(|f| !f.is_empty() && !f.starts_with("dep:") && !f.contains('/'))
                .map(str::to_string)
                .collect();
            out.insert(name.trim().to_string(), implied);
        }
        out
    }

    /// `row` with every implied feature added.
    fn closure(row: &[&str], all: &BTreeMap<String, Vec<String>>) -> BTreeSet<String> {
        let mut on: BTreeSet<String> = row.iter().map(|f| f.to_string()).collect();
        loop {
            let implied: Vec<String> = on
                .iter()
                .flat_map(|f| all[f].iter().cloned())
                .filter(|f| !on.contains(f))
                .collect();
            if implied.is_empty() {
                return on;
            }
            on.extend(implied);
        }
    }

    /// With `base` added to every row (a board, which may imply features
    /// of its own): every feature of `manifest` but `skip` and those `base`
    /// implies is on in a row and off in another; each `fusion-*` feature
    /// is, with `base`'s, a row's only estimator feature, and one row has
    /// only `base`'s.
    fn check(manifest: &str, rows: &[&[&str]], skip: &[&str], base: &[&str]) {
        let all = features(manifest);
        let base = closure(base, &all);
        let rows: Vec<BTreeSet<String>> = rows
            .iter()
            .inspect(|row| {
                for f in row.iter() {
                    assert!(all.contains_key(*f), "{manifest} has no feature `{f}`");
                }
            })
            .map(|row| {
                let mut on = closure(row, &all);
                on.extend(base.iter().cloned());
                on
            })
            .collect();
        for f in all
            .keys()
            .filter(|f| !skip.contains(&f.as_str()) && !base.contains(*f))
        {
            assert!(rows.iter().any(|r| r.contains(f)), "`{f}` never on");
            assert!(rows.iter().any(|r| !r.contains(f)), "`{f}` never off");
        }
        let estimators = |r: &BTreeSet<String>| -> BTreeSet<String> {
            r.iter()
                .filter(|f| f.starts_with("fusion-"))
                .cloned()
                .collect()
        };
        assert!(rows.iter().any(|r| estimators(r) == estimators(&base)));
        for f in all.keys().filter(|f| f.starts_with("fusion-")) {
            let mut alone = closure(&[f.as_str()], &all);
            alone.extend(estimators(&base));
            assert!(
                rows.iter().any(|r| estimators(r) == alone),
                "`{f}` never the only estimator feature"
            );
        }
    }

    #[test]
    fn core_rows_cover_every_choice() {
        check(
            "core/Cargo.toml",
            &CORE,
            &["default", "std", "schemars", "arbitrary"],
            &[],
        );
        let has = |r: &&[&str], f: &str| r.contains(&f);
        // The default backend, each other one alone and both together.
        assert!(CORE.iter().any(|r| !has(r, "libm") && !has(r, "micromath")));
        assert!(CORE.iter().any(|r| has(r, "libm") && !has(r, "micromath")));
        assert!(CORE.iter().any(|r| !has(r, "libm") && has(r, "micromath")));
        assert!(CORE.iter().any(|r| has(r, "libm") && has(r, "micromath")));
        // Each host-tool feature alone on the host.
        for host_feature in ["std", "schemars", "arbitrary"] {
            assert!(
                super::CORE_HOST.iter().any(|r| r.contains(&host_feature)),
                "`{host_feature}` never built on the host"
            );
        }
    }

    #[test]
    fn firmware_rows_cover_every_choice() {
        let boards: Vec<&str> = crate::BOARDS.iter().map(|(_, f)| *f).collect();
        // `panic-never` is the proof's panic handler, not a user's choice:
        // `cargo xtask panic-free` builds it (`xtask/src/panic_free.rs`).
        let mut skip = vec!["default", "panic-never"];
        skip.extend(&boards);
        // Every row runs with each board; both boards imply the same
        // features (`fusion-ekf`).
        let manifest = features("firmware/Cargo.toml");
        let implied = |board: &str| closure(&[board], &manifest);
        assert!(boards.iter().all(|b| {
            let mut a = implied(b);
            let mut z = implied(boards[0]);
            a.remove(*b);
            z.remove(boards[0]);
            a == z
        }));
        check("firmware/Cargo.toml", &FIRMWARE, &skip, &[boards[0]]);
        assert!(
            FIRMWARE
                .iter()
                .all(|r| r.iter().all(|f| !boards.contains(f))),
            "the board is added per run"
        );
    }
}
