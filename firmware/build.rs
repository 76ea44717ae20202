//! Links the firmware for the STM32F4 memory map of the workspace's
//! `memory.x` (at its top: the robot board's map)
//! (on `thumb*` targets only; host builds of the stub need nothing), and
//! includes a robot image when `WMR_ROBOT_IMAGE` names one.

use std::{env, fs, path::PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=../memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    // `cargo xtask firmware --robot FILE`: the robot image (`firmware-sim
    // robot-image`) replaces the Black Pill's compiled-in configuration.
    println!("cargo::rustc-check-cfg=cfg(wmr_robot_image)");
    println!("cargo:rerun-if-env-changed=WMR_ROBOT_IMAGE");
    if let Some(image) = env::var_os("WMR_ROBOT_IMAGE") {
        let image = PathBuf::from(image);
        println!("cargo:rerun-if-changed={}", image.display());
        let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
        fs::copy(&image, out.join("robot.bin"))
            .unwrap_or_else(|e| panic!("WMR_ROBOT_IMAGE {}: {e}", image.display()));
        println!("cargo:rustc-cfg=wmr_robot_image");
    }
    let target = env::var("TARGET").unwrap_or_default();
    if !target.starts_with("thumb") {
        return;
    }
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::copy("../memory.x", out.join("memory.x")).expect("copy ../memory.x into OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
