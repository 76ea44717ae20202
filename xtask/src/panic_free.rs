//! `cargo xtask panic-free`: the link-time proof that the release firmware
//! cannot panic.
//!
//! Each build is the release firmware (`--bin wmr-firmware`, LTO, the
//! release profile as shipped) with the feature `panic-never`, whose panic
//! handler calls a function that nothing defines
//! (`firmware/src/main.rs`). The linker keeps the handler only if a code
//! path still reaches it, and then fails on the undefined symbol
//! `wmr_firmware_has_a_panic_path`; a build that links has no panic path.
//! With the usual handler in its place (semihosting exit, `panic-probe`),
//! nothing references it either, so the shipped ELF is the proved code.
//!
//! The matrix: each board in its default configuration, and each board
//! with each estimator feature of `firmware/Cargo.toml` alone (the rows
//! of [`rows`]; a test checks them against the manifest); then the Black
//! Pill with the robot image of [`ROUTE_ROBOT`] (`cargo xtask firmware
//! --robot`), the build that links the MAVLink endpoint and mission runner
//! on its UART (a robot image with a route: docs/mavlink.md). Each row is
//! one release build of the firmware crate and the core with that feature
//! set, in xtask's own target directory.

use std::time::Instant;

/// The feature sets proved for each board, besides the board's own
/// feature: the default (none), `fusion-ekf` (which the boards imply, so
/// its row repeats the default; kept, so that the list stays one row per
/// estimator feature), then each optional build of
/// [`wmr_core::builds::OPTIONAL_BUILDS`] alone.
pub fn rows() -> Vec<Vec<&'static str>> {
    [vec![], vec!["fusion-ekf"]]
        .into_iter()
        .chain(
            wmr_core::builds::OPTIONAL_BUILDS
                .iter()
                .map(|build| vec![build.feature]),
        )
        .collect()
}

/// The robot file whose image (a route in it) the Black Pill's last row
/// is built with: its MAVLink endpoint is linked only with a route.
pub const ROUTE_ROBOT: &str = "robots/route_loop.toml";

/// The undefined symbol the `panic-never` handler calls.
const SENTINEL: &str = "wmr_firmware_has_a_panic_path";

/// Builds every row for every board; fails on the first that does not link,
/// and says what that means.
pub fn panic_free() -> crate::Result {
    let started = Instant::now();
    let mut proved = Vec::new();
    for (board, board_feature) in crate::BOARDS {
        for row in rows() {
            let features: Vec<&str> = std::iter::once(board_feature)
                .chain(row.iter().copied())
                .chain(std::iter::once("panic-never"))
                .collect();
            let name = if row.is_empty() {
                "default".to_string()
            } else {
                row.join("+")
            };
            crate::step(&format!("panic-free {board} [{name}]"), || {
                crate::target::Build {
                    bins: &["wmr-firmware"],
                    no_default_features: true,
                    features: &features,
                    env: &[],
                }
                .run(&format!("panic-free-{board}-{name}"))
                .map(|_| ())
                .map_err(|e| {
                    format!(
                        "{e}\n\nThe release firmware for {board} [{name}] has a panic path: \
                         the link failed if it names `{SENTINEL}`. Find the call: build \
                         the same features without `panic-never` and list the calls \
                         into `core::panicking`, `core::cell::panic_*`, `*unwrap_failed` \
                         or `*expect_failed` (`llvm-objdump -d -C ELF`); remove the path \
                         (docs/firmware.md, \"Panic freedom\")"
                    )
                })
            })?;
            proved.push(format!("{board} [{name}]"));
        }
    }
    proved.push(route_image_row()?);
    eprintln!(
        "\npanic-free: {} release builds link with the never-linking panic handler \
         ({:.0} s): {}",
        proved.len(),
        started.elapsed().as_secs_f64(),
        proved.join(", ")
    );
    Ok(())
}

/// The Black Pill built with [`ROUTE_ROBOT`]'s image (validated and
/// written by `firmware-sim robot-image`, as `cargo xtask firmware
/// --robot` does), with the features the image needs and `panic-never`.
fn route_image_row() -> Result<String, String> {
    let root = crate::target::workspace_root();
    let file = root.join(ROUTE_ROBOT);
    let dir = crate::target::target_dir().join("panic-free");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let image = dir.join("route_loop.robot");
    let mut extra = Vec::new();
    crate::step(&format!("write {ROUTE_ROBOT}'s image"), || {
        extra = crate::robot::robot_image(&file, &image)?;
        Ok(())
    })?;
    let image_arg = image.to_string_lossy().into_owned();
    let features: Vec<&str> = ["board-blackpill"]
        .into_iter()
        .chain(extra.iter().map(String::as_str))
        .chain(["panic-never"])
        .collect();
    let name = format!("blackpill [{ROUTE_ROBOT}: route, MAVLink endpoint]");
    crate::step(&format!("panic-free {name}"), || {
        crate::target::Build {
            bins: &["wmr-firmware"],
            no_default_features: true,
            features: &features,
            env: &[("WMR_ROBOT_IMAGE", &image_arg)],
        }
        .run("panic-free-blackpill-route")
        .map(|_| ())
        .map_err(|e| {
            format!(
                "{e}\n\nThe Black Pill firmware with {ROUTE_ROBOT}'s image has a panic path: \
                 the link failed if it names `{SENTINEL}` (docs/firmware.md, \"Panic freedom\")"
            )
        })
    })?;
    Ok(name)
}

#[cfg(test)]
mod tests {
    use super::rows;

    /// Every estimator feature of the firmware (a `fusion-*` feature or
    /// `wheel-speed-observer`) is proved alone, and the default is proved;
    /// the optional ones are exactly `wmr_core::builds::OPTIONAL_BUILDS`.
    #[test]
    fn rows_cover_every_estimator_feature() {
        let manifest =
            std::fs::read_to_string(crate::target::workspace_root().join("firmware/Cargo.toml"))
                .unwrap();
        let table: toml::Table = manifest.parse().unwrap();
        let features = table["features"].as_table().unwrap();
        let estimators: Vec<&str> = features
            .keys()
            .map(String::as_str)
            .filter(|f| f.starts_with("fusion-") || *f == "wheel-speed-observer")
            .collect();
        assert!(!estimators.is_empty());
        let rows = rows();
        for f in &estimators {
            assert!(rows.iter().any(|r| r == &[*f]), "`{f}` is not proved alone");
        }
        assert!(rows.iter().any(|r| r.is_empty()), "no default row");
        assert_eq!(rows.len(), estimators.len() + 1);
        let mut optional: Vec<&str> = estimators
            .into_iter()
            .filter(|f| *f != "fusion-ekf")
            .collect();
        let mut listed: Vec<&str> = wmr_core::builds::OPTIONAL_BUILDS
            .iter()
            .map(|b| b.feature)
            .collect();
        optional.sort_unstable();
        listed.sort_unstable();
        assert_eq!(optional, listed, "wmr_core::builds::OPTIONAL_BUILDS");
    }
}
