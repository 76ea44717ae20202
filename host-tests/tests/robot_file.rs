//! One robot file for the simulator and the flash:
//! a scenario naming its robot runs exactly as the same robot written in
//! the scenario; a bad robot file is refused naming the file, key and
//! reason; and the Black Pill firmware built with a robot image carries
//! exactly the configuration the simulator validated.
//!
//! The firmware test builds the Black Pill board for
//! `thumbv7em-none-eabihf` into `target/robot-firmware` (a target directory
//! of its own, so that the nested cargo never waits on this test's build
//! lock), as `cargo xtask firmware --robot robots/blackpill.toml` does.

use std::path::{Path, PathBuf};
use std::process::Command;

use firmware_sim::hil::{FIRMWARE_TARGET, workspace_root};
use firmware_sim::scenario::robot::{FlashFloor, Robot};
use firmware_sim::{Scenario, run};
use wmr_core::devices::tag_grid::TagGridSpec;
use wmr_core::devices::{TagId, TagLocator};
use wmr_core::pilot::spec::SpecError;
use wmr_link::image::{self, ImageFloor, MAGIC};

fn robots() -> PathBuf {
    workspace_root().join("robots")
}

/// `robots/figure_eight.toml` (which names `example.toml`) and the
/// embedded `figure_eight_rfid_full_stack` (the same robot written in the
/// scenario) give the same records, bit for bit.
#[test]
fn a_scenario_naming_its_robot_runs_as_the_same_robot_inline() {
    let mut named = Scenario::from_file(&robots().join("figure_eight.toml")).unwrap();
    let mut inline = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
    named.duration_s = 60.0;
    inline.duration_s = 60.0;
    named.transient_s = 10.0;
    inline.transient_s = 10.0;
    // Resolved: the scenario holds the robot's tables.
    assert_eq!(named.robot, None);
    assert_eq!(named.plant, inline.plant);
    assert_eq!(named.position, inline.position);
    let a = run(&named, |_, _| {}).unwrap();
    let b = run(&inline, |_, _| {}).unwrap();
    assert_eq!(a.records.len(), 6_000);
    assert!(a.records == b.records, "the records differ");
    assert_eq!(
        a.summary.max_error_m.to_bits(),
        b.summary.max_error_m.to_bits()
    );
}

/// A robot embedded as `[robot]` is the same robot.
#[test]
fn an_embedded_robot_is_the_same_robot() {
    let robot = std::fs::read_to_string(robots().join("example.toml")).unwrap();
    let robot: toml::Table = robot.parse().unwrap();
    let mut scenario: toml::Table = std::fs::read_to_string(robots().join("figure_eight.toml"))
        .unwrap()
        .parse()
        .unwrap();
    scenario.insert("robot".into(), toml::Value::Table(robot));
    let embedded = Scenario::from_toml_str(&toml::to_string(&scenario).unwrap()).unwrap();
    let named = Scenario::from_file(&robots().join("figure_eight.toml")).unwrap();
    assert_eq!(embedded, named);
}

/// A key the robot's setup ignores is a warning naming the robot file and
/// the key as the robot file names it, whether the scenario names the
/// robot, embeds it or the robot is flashed; none without the key.
#[test]
fn a_robot_key_that_does_not_apply_is_a_warning_in_the_robot_files_names() {
    let dir = temp_dir("warnings");
    let example = std::fs::read_to_string(robots().join("example.toml")).unwrap();
    assert!(example.contains("mode = \"paper\""));
    let robot = dir.join("radius.toml");
    std::fs::write(
        &robot,
        example.replace("mode = \"paper\"", "mode = \"paper\"\nread_radius_m = 0.05"),
    )
    .unwrap();
    let scenario = std::fs::read_to_string(robots().join("figure_eight.toml"))
        .unwrap()
        .replace("robot = \"example.toml\"", "robot = \"radius.toml\"");
    std::fs::write(dir.join("scenario.toml"), scenario).unwrap();
    let expected = format!(
        "robot file {}: reader.read_radius_m: ignored with reader.mode = \"paper\"",
        robot.display()
    );
    let named = Scenario::from_file(&dir.join("scenario.toml")).unwrap();
    let w = named.warnings();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(w[0].starts_with(&expected), "{w:?}");
    let w = Robot::from_file(&robot).unwrap().warnings();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(w[0].starts_with(&expected), "{w:?}");
    // Embedded as [robot]: the same key, in the robot's names.
    let robot_table: toml::Table = std::fs::read_to_string(&robot).unwrap().parse().unwrap();
    let mut scenario: toml::Table = std::fs::read_to_string(robots().join("figure_eight.toml"))
        .unwrap()
        .parse()
        .unwrap();
    scenario.insert("robot".into(), toml::Value::Table(robot_table));
    let embedded = Scenario::from_toml_str(&toml::to_string(&scenario).unwrap()).unwrap();
    let w = embedded.warnings();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].starts_with("robot file [robot]: reader.read_radius_m: ignored"),
        "{w:?}"
    );
    // The shipped robots give no such key.
    for name in [
        "example.toml",
        "blackpill.toml",
        "surveyed.toml",
        "route_loop.toml",
    ] {
        let w = Robot::from_file(&robots().join(name)).unwrap().warnings();
        assert_eq!(w, Vec::<String>::new(), "{name}");
    }
    let w = Scenario::from_file(&robots().join("figure_eight.toml"))
        .unwrap()
        .warnings();
    assert_eq!(w, Vec::<String>::new());
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = workspace_root()
        .join("target")
        .join("robot-file-tests")
        .join(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A bad value is refused naming the robot file, its key and the rule; a
/// scenario that also sets a robot table is refused naming the key.
#[test]
fn errors_name_the_file_the_key_and_the_reason() {
    let dir = temp_dir("errors");
    let example = std::fs::read_to_string(robots().join("example.toml")).unwrap();
    let cases = [
        (
            "wheel_radius_m = 0.03",
            "wheel_radius_m = -0.03",
            "plant.wheel_radius_m",
            "must be in [0.001, 2] m (got -0.03)",
        ),
        (
            "k2 = 0.11",
            "k2 = 0.0",
            "controller.k2",
            "must be in [0.000001, 10000] m/s (got 0)",
        ),
        (
            "spacing_m = 0.1",
            "spacing_m = 0.0",
            "floor.spacing_m",
            "must be in [0.01, 10] m (got 0)",
        ),
        (
            "max_wheel_speed_rad_s = 18.0",
            "max_wheel_speed_rad_s = -1.0",
            "drive.max_wheel_speed_rad_s",
            "must be in [0.001, 10000] rad/s (got -1)",
        ),
        (
            "antenna_offset_m = 0.0",
            "antenna_offset_m = 2.0",
            "reader",
            "antenna",
        ),
        (
            "every_ticks = 10",
            "every_ticks = 0",
            "telemetry.every_ticks",
            "must be 1 to 65535 ticks (got 0)",
        ),
        (
            "every_ticks = 10",
            "every_ticks = 65536",
            "telemetry.every_ticks",
            "must be 1 to 65535 ticks (got 65536)",
        ),
    ];
    for (from, to, key, reason) in cases {
        assert!(example.contains(from), "{from}");
        let robot = dir.join("bad.toml");
        std::fs::write(&robot, example.replace(from, to)).unwrap();
        let scenario = std::fs::read_to_string(robots().join("figure_eight.toml"))
            .unwrap()
            .replace("robot = \"example.toml\"", "robot = \"bad.toml\"");
        let file = dir.join("scenario.toml");
        std::fs::write(&file, scenario).unwrap();
        let e = Scenario::from_file(&file).unwrap_err().to_string();
        assert!(e.contains(&robot.display().to_string()), "{to}: {e}");
        assert!(e.contains(&format!("`{key}")), "{to}: {e}");
        assert!(e.contains(reason), "{to}: {e}");
        // The flash image is refused the same way.
        let e = Robot::from_file(&robot)
            .unwrap()
            .flash_image()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!("`{key}")) && e.contains(reason),
            "{to}: {e}"
        );
    }
    // An unknown key: the file and the key.
    std::fs::write(
        dir.join("bad.toml"),
        example.replace("k2 = 0.11", "k2 = 0.11\nk4 = 1.0"),
    )
    .unwrap();
    let e = Robot::from_file(&dir.join("bad.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("bad.toml") && e.contains("k4"), "{e}");
    // A robot table in the scenario too.
    let scenario = std::fs::read_to_string(robots().join("figure_eight.toml")).unwrap()
        + "\n[observer]\ngain_per_m = 0.5\n";
    let file = robots().join("figure_eight.toml");
    let e = Scenario::from_toml_str_in(&scenario, file.parent())
        .unwrap_err()
        .to_string();
    assert!(e.contains("`observer`") && e.contains("robot"), "{e}");
    // A position key other than the reader's faults is the robot's.
    for (table, key) in [
        (
            "kind = \"reader\"\nspacing_m = 0.2\nseed = 3",
            "position.spacing_m",
        ),
        ("kind = \"reader\"\nmode = \"range\"", "position.mode"),
        ("kind = \"nearest_tag\"", "position.kind"),
    ] {
        let scenario = std::fs::read_to_string(robots().join("figure_eight.toml")).unwrap()
            + "\n[position]\n"
            + table
            + "\n";
        let e = Scenario::from_toml_str_in(&scenario, file.parent())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!("`{key}`")) && e.contains("robot"),
            "{e}"
        );
    }
    // A tag map: 40-bit ids, no duplicates.
    let map = dir.join("tags.csv");
    std::fs::write(&map, "id,x_m,y_m\n1,0,0\n1,1,1\n").unwrap();
    let robot = example.replace(
        "kind = \"grid\"\nspacing_m = 0.1\noffset_m = [0.0, 0.0]",
        "kind = \"tag_map\"\nfile = \"tags.csv\"",
    );
    std::fs::write(dir.join("map.toml"), &robot).unwrap();
    let e = Robot::from_file(&dir.join("map.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("tags.csv") && e.contains("0x1 appears twice"),
        "{e}"
    );
    std::fs::write(&map, "0x10000000000,0,0\n").unwrap();
    let e = Robot::from_file(&dir.join("map.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 1") && e.contains("40 bits"), "{e}");
}

/// The Black Pill's robot file is the board's compiled-in default
/// (`PILOT` and `SITE_TAGS` in `firmware/src/board/blackpill.rs` and
/// `tags.rs`, restated here as numbers).
#[test]
fn the_blackpill_robot_file_is_the_boards_default() {
    let image = Robot::from_file(&robots().join("blackpill.toml"))
        .unwrap()
        .flash_image()
        .unwrap();
    let p = image.pilot;
    // TELEMETRY_EVERY_TICKS.
    assert_eq!(image.telemetry_every_ticks, 10);
    assert_eq!(p.tracker.period_s, 0.01);
    assert_eq!(p.tracker.gains, [0.11, 0.11, 0.1]);
    assert_eq!(p.tracker.observer_gain_per_m, 0.6);
    assert_eq!(p.tracker.fix_timeout_ticks, 50);
    assert_eq!(p.tracker.sensors.tag_spacing_m, 0.0);
    assert_eq!(p.drive.wheel_radius_m, 0.03);
    assert_eq!(p.drive.track_width_m, 0.2);
    assert_eq!(p.drive.max_wheel_speed_rad_s, 18.0);
    assert_eq!(p.drive.feedforward_duty_per_rad_s, 0.05);
    assert_eq!(p.drive.kp_duty_per_rad_s, 0.02);
    assert_eq!(p.encoder_bits, 16);
    let FlashFloor::Map(tags) = &image.floor else {
        panic!("a tag map")
    };
    assert_eq!(tags.len(), 7);
    assert_eq!(tags[0], (TagId(0x01_0000_0001), [0.0, -5.0]));
    assert_eq!(tags[1], (TagId(0x01_0000_0002), [-5.0, -3.535_534]));
    // The example robot's grid floor (a 10 cm grid around the figure-eight).
    let example = Robot::from_file(&robots().join("example.toml"))
        .unwrap()
        .flash_image()
        .unwrap();
    let FlashFloor::Grid(TagGridSpec { spacing_m, .. }) = example.floor else {
        panic!("a grid")
    };
    assert_eq!(spacing_m, 0.1);
    // On a tag map the fusion estimator needs a range reader (the
    // nearest-tag reader's cell measurements need a grid's spacing) and an
    // explicit blind distance (its default is derived from the spacing).
    let dir = temp_dir("fusion-map");
    let text = std::fs::read_to_string(robots().join("blackpill.toml"))
        .unwrap()
        .replace(
            "file = \"blackpill_tags.csv\"",
            &format!("file = {:?}", robots().join("blackpill_tags.csv")),
        );
    let image = |text: String| {
        std::fs::write(dir.join("fusion.toml"), text).unwrap();
        Robot::from_file(&dir.join("fusion.toml"))
            .unwrap()
            .flash_image()
    };
    let fusion = "\n[estimator.fusion]\nfilter = \"ekf\"\n";
    let e = image(text.clone() + fusion).unwrap_err().to_string();
    assert!(
        e.contains("`floor.kind`") && e.contains("range reader") && e.contains("tag_spacing_m"),
        "{e}"
    );
    let range = text.replace(
        "mode = \"paper\"",
        "mode = \"range\"\nread_radius_m = 0.08\nrepeat_interval_s = 0.1",
    );
    let e = image(range.clone() + fusion).unwrap_err().to_string();
    assert!(
        e.contains("`floor.kind`") && e.contains("max_blind_distance_m must be given"),
        "{e}"
    );
    let image = image(range + fusion + "max_blind_distance_m = 12.0\n").unwrap();
    let wmr_core::estimation::spec::EstimatorSpec::Fusion(spec) = image.pilot.tracker.estimator
    else {
        panic!("the fusion estimator")
    };
    assert_eq!(spec.max_blind_distance_m, Some(12.0));
    assert_eq!(image.pilot.tracker.sensors.read_radius_m, 0.08);
    assert!(matches!(image.floor, FlashFloor::Map(_)));
    let _ = SpecError::NotInThisBuild;
}

/// The Black Pill's build of the firmware crate for size, as xtask gives
/// it to cargo on every Black Pill build (`xtask/src/target.rs`,
/// `BLACKPILL_CONFIG`, which says why; an xtask test checks that the two
/// agree).
const BLACKPILL_CONFIG: &str = "profile.release.package.wmr-firmware.opt-level=\"z\"";

/// One Black Pill build at a time: each test's build writes the same ELF.
static BLACKPILL_BUILD: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The Black Pill firmware built with `image` in flash (as
/// [`build_blackpill_with`]), read while no other test's build can
/// replace it.
fn blackpill_elf_with(image: &Path) -> Vec<u8> {
    let _one_at_a_time = BLACKPILL_BUILD
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    std::fs::read(build_blackpill_with(image)).unwrap()
}

/// Builds the Black Pill firmware with `image` in flash, into
/// `WMR_FIRMWARE_TARGET_DIR` if set (`cargo xtask ci` gives its own, where
/// the firmware's dependencies are built), else `target/robot-firmware`.
fn build_blackpill_with(image: &Path) -> PathBuf {
    let root = workspace_root();
    let dir = std::env::var_os("WMR_FIRMWARE_TARGET_DIR").map_or_else(
        || root.join("target").join("robot-firmware"),
        |dir| root.join(dir),
    );
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let status = Command::new(cargo)
        .current_dir(&root)
        .args([
            "build",
            "--quiet",
            "--release",
            "--config",
            BLACKPILL_CONFIG,
            "-p",
            "wmr-firmware",
            "--bin",
            "wmr-firmware",
        ])
        .args([
            "--target",
            FIRMWARE_TARGET,
            "--no-default-features",
            "--features",
            "board-blackpill",
        ])
        .arg("--target-dir")
        .arg(&dir)
        .env("WMR_ROBOT_IMAGE", image)
        .status()
        .unwrap();
    assert!(status.success(), "building the Black Pill firmware failed");
    dir.join(FIRMWARE_TARGET)
        .join("release")
        .join("wmr-firmware")
}

/// The firmware built from `robots/blackpill.toml` holds, in its ELF, the
/// very image the simulator made of the file: decoded from the ELF, the
/// same pilot spec and the same tags as what `firmware-sim` parses.
#[test]
fn the_flashed_configuration_is_the_simulators() {
    // The Black Pill's robot with its telemetry at 25 ticks (not the
    // board's constant 10): the image carries the robot file's.
    let dir = temp_dir("flash");
    let text = std::fs::read_to_string(robots().join("blackpill.toml")).unwrap();
    assert!(text.contains("every_ticks = 10"));
    std::fs::write(
        dir.join("blackpill.toml"),
        text.replace("every_ticks = 10", "every_ticks = 25"),
    )
    .unwrap();
    std::fs::copy(
        robots().join("blackpill_tags.csv"),
        dir.join("blackpill_tags.csv"),
    )
    .unwrap();
    let robot = Robot::from_file(&dir.join("blackpill.toml")).unwrap();
    let expected = robot.flash_image().unwrap();
    assert_eq!(expected.telemetry_every_ticks, 25);
    let image_file = dir.join("blackpill.robot");
    std::fs::write(&image_file, &expected.bytes).unwrap();
    let elf = blackpill_elf_with(&image_file);
    let found: Vec<usize> = elf
        .windows(MAGIC.len())
        .enumerate()
        .filter(|(_, w)| *w == MAGIC)
        .map(|(at, _)| at)
        .collect();
    let decoded: Vec<_> = found
        .iter()
        .filter_map(|&at| {
            let bytes = elf.get(at..at + expected.bytes.len())?;
            image::decode(bytes).ok().map(|i| (bytes, i))
        })
        .collect();
    assert_eq!(
        decoded.len(),
        1,
        "one image in the ELF (magic at {found:?})"
    );
    let (bytes, image) = &decoded[0];
    assert_eq!(*bytes, expected.bytes.as_slice());
    assert_eq!(image.pilot, expected.pilot);
    assert_eq!(image.telemetry_every_ticks, 25);
    assert!(image.pilot.build().is_ok());
    let ImageFloor::Map(tags) = image.floor else {
        panic!("a tag map")
    };
    let FlashFloor::Map(expected_tags) = &expected.floor else {
        panic!("a tag map")
    };
    assert_eq!(
        tags.iter().collect::<Vec<_>>(),
        expected_tags
            .iter()
            .map(|(id, [x, y])| (*id, wmr_core::geometry::Vec2::new(*x, *y)))
            .collect::<Vec<_>>()
    );
    for (id, [x, y]) in expected_tags {
        assert_eq!(
            image.floor.locate(*id),
            Some(wmr_core::geometry::Vec2::new(*x, *y))
        );
    }
}

/// Flash of a firmware ELF (32-bit, little-endian), bytes: the sizes of
/// its sections stored in flash, `.vector_table + .text + .rodata +
/// .data`, from its section headers (as `cargo xtask size` counts it).
fn flash_bytes(elf: &[u8]) -> u64 {
    let u16_at = |at: usize| u16::from_le_bytes([elf[at], elf[at + 1]]) as usize;
    let u32_at = |at: usize| u32::from_le_bytes(elf[at..at + 4].try_into().unwrap()) as usize;
    assert_eq!(&elf[..6], b"\x7fELF\x01\x01", "a 32-bit little-endian ELF");
    let (headers, entry_size, count) = (u32_at(0x20), u16_at(0x2e), u16_at(0x30));
    let header = |i: usize| headers + i * entry_size;
    let names = u32_at(header(u16_at(0x32)) + 0x10);
    let name = |i: usize| {
        let start = names + u32_at(header(i));
        let end = start + elf[start..].iter().position(|&b| b == 0).unwrap();
        std::str::from_utf8(&elf[start..end]).unwrap()
    };
    (0..count)
        .filter(|&i| [".vector_table", ".text", ".rodata", ".data"].contains(&name(i)))
        .map(|i| u32_at(header(i) + 0x14) as u64)
        .sum()
}

/// The Black Pill firmware with a route in its image
/// (`robots/route_loop.toml`, as `cargo xtask firmware --robot` builds
/// it): its flash against its budget `[robot_flash_bytes] route_loop` in
/// `firmware/budgets.toml` (over by more than the file's `tolerance` fails,
/// as xtask's budgets do) and its hard limit `[robot_flash_limit_bytes]
/// route_loop` (80 KiB: the image's route brings the MAVLink endpoint).
/// One more build of the firmware crate alone: its dependencies are the
/// Black Pill builds' of `cargo xtask ci`.
#[test]
fn the_blackpill_firmware_with_a_route_fits_its_flash() {
    let robot = Robot::from_file(&robots().join("route_loop.toml")).unwrap();
    let image = robot.flash_image().unwrap();
    let image_file = temp_dir("route-flash").join("route_loop.robot");
    std::fs::write(&image_file, &image.bytes).unwrap();
    let flash = flash_bytes(&blackpill_elf_with(&image_file)) as f64;

    let text = std::fs::read_to_string(workspace_root().join("firmware").join("budgets.toml"))
        .expect("read firmware/budgets.toml");
    let budgets: toml::Table = text.parse().expect("parse firmware/budgets.toml");
    let number = |v: &toml::Value| v.as_integer().map(|i| i as f64).or_else(|| v.as_float());
    let entry = |table: &str, name: &str| {
        budgets
            .get(table)
            .and_then(|t| t.get(name))
            .and_then(number)
            .unwrap_or_else(|| panic!("firmware/budgets.toml has no [{table}] {name}"))
    };
    let budget = entry("robot_flash_bytes", "route_loop");
    let limit = entry("robot_flash_limit_bytes", "route_loop");
    let tolerance = budgets
        .get("tolerance")
        .and_then(number)
        .expect("tolerance");
    println!(
        "Black Pill with robots/route_loop.toml: flash {flash} B, budget {budget} B, limit {limit} B"
    );
    assert!(
        flash <= budget * (1.0 + tolerance),
        "the Black Pill firmware with robots/route_loop.toml: {flash} B of flash, over its \
         budget of {budget} B"
    );
    assert!(
        flash <= limit,
        "the Black Pill firmware with robots/route_loop.toml: {flash} B of flash, over the \
         board's limit of {limit} B"
    );
}

/// A robot on `floor` (the `[floor]` table's body) with its reader in
/// `mode` (8 cm read radius in `range` mode), tracking a 1 m circle for 60 s: the scenario file, in `dir`.
fn circle_robot(dir: &Path, name: &str, mode: &str, floor: &str) -> PathBuf {
    let example = std::fs::read_to_string(robots().join("example.toml")).unwrap();
    let grid = "kind = \"grid\"\nspacing_m = 0.1\noffset_m = [0.0, 0.0]";
    assert!(example.contains(grid) && example.contains("mode = \"paper\""));
    let robot = example.replace(grid, floor).replace(
        "mode = \"paper\"",
        &format!("mode = \"{mode}\"\nread_radius_m = 0.08"),
    );
    std::fs::write(dir.join(format!("{name}.toml")), robot).unwrap();
    let scenario = format!(
        "name = \"{name}\"\nduration_s = 60.0\ntransient_s = 10.0\nrobot = \"{name}.toml\"\n\n\
         [reference]\nkind = \"circle\"\nradius_m = 1.0\nrate_rad_s = 0.2\n\n\
         [initial]\nx_m = 1.02\ny_m = -0.01\nheading_rad = 1.5707963267948966\n"
    );
    let file = dir.join(format!("{name}-scenario.toml"));
    std::fs::write(&file, scenario).unwrap();
    file
}

/// `run.csv` and `summary.json` of `result`, the summary without its
/// scenario name and wall time.
fn outputs(dir: &Path, result: &firmware_sim::RunResult) -> (Vec<u8>, String) {
    std::fs::create_dir_all(dir).unwrap();
    let (csv, json) = (dir.join("run.csv"), dir.join("summary.json"));
    firmware_sim::output::write_csv(&csv, &result.records).unwrap();
    firmware_sim::output::write_summary(&json, &result.summary).unwrap();
    let summary = std::fs::read_to_string(json).unwrap();
    let summary: Vec<&str> = summary
        .lines()
        .filter(|l| !l.contains("\"scenario\":") && !l.contains("\"wall_time_s\":"))
        .collect();
    assert!(summary.len() > 20, "a summary");
    (std::fs::read(csv).unwrap(), summary.join("\n"))
}

/// A tag-map floor (`floor.kind = "tag_map"`, arbitrary ids) that
/// lays out the tags of a grid runs as that grid: the reader reads the
/// same tag (nearest; within the read radius in `range` mode) and the
/// robot resolves the map's id to the same position, so `run.csv` (which
/// has no ids) is the same byte for byte, and so is `summary.json` (tag
/// count, reader and core counters included). The grid's spacing,
/// 12.5 cm, and lattice are exact in `f32` and `f64`, so the map's
/// positions are the grid's to the bit.
#[test]
fn a_tag_map_floor_runs_as_the_grid_it_lays_out() {
    use firmware_sim::scenario::PositionSetup;
    use firmware_sim::tags::Floor;
    use wmr_core::devices::TagGrid;
    use wmr_core::geometry::Vec2;

    let dir = temp_dir("tag-map-as-grid");
    for mode in ["paper", "range"] {
        let grid_file = circle_robot(
            &dir,
            &format!("grid-{mode}"),
            mode,
            "kind = \"grid\"\nspacing_m = 0.125",
        );
        let grid = Scenario::from_file(&grid_file).unwrap();
        let PositionSetup::Reader(Floor::Grid(floor), _) = grid.validate().unwrap().position else {
            panic!("a grid reader")
        };
        let (lo, _) = floor.bounds();
        let mut csv = String::from("id,x_m,y_m\n");
        let mut n = 0_u64;
        for row in 0..floor.grid().rows() {
            for column in 0..floor.grid().columns() {
                let (x, y) = (
                    lo[0] + f64::from(column) * 0.125,
                    lo[1] + f64::from(row) * 0.125,
                );
                let at = floor.grid().position(TagGrid::id(row, column)).unwrap();
                assert_eq!(at, Vec2::new(x as f32, y as f32), "exact lattice");
                // Arbitrary, distinct 40-bit ids (an odd multiplier is a
                // bijection modulo 2^40).
                let id = (n.wrapping_mul(0x9E37_79B9) + 0x0001_2345_6789) & TagId::MASK;
                csv += &format!("{id:#x},{x},{y}\n");
                n += 1;
            }
        }
        std::fs::write(dir.join(format!("map-{mode}.csv")), csv).unwrap();
        let map_file = circle_robot(
            &dir,
            &format!("map-{mode}"),
            mode,
            &format!("kind = \"tag_map\"\nfile = \"map-{mode}.csv\""),
        );
        let map = Scenario::from_file(&map_file).unwrap();
        assert_eq!(map.floor_tags.len(), floor.len());
        let a = run(&grid, |_, _| {}).unwrap();
        let b = run(&map, |_, _| {}).unwrap();
        let (csv_a, summary_a) = outputs(&dir.join(format!("out-grid-{mode}")), &a);
        let (csv_b, summary_b) = outputs(&dir.join(format!("out-map-{mode}")), &b);
        assert!(csv_a == csv_b, "{mode}: run.csv differs");
        assert!(summary_a == summary_b, "{mode}:\n{summary_a}\n{summary_b}");
        // Not a vacuous run: the reader read map tags, the robot knew them.
        let rfid = b.summary.rfid.unwrap();
        assert!(rfid.frames_ok > 100, "{mode}: {} frames", rfid.frames_ok);
        assert_eq!(rfid.unknown_tags, 0, "{mode}");
        assert!(
            b.summary.rms_error_m < 0.1,
            "{mode}: {}",
            b.summary.rms_error_m
        );
    }
}

/// The example tag-map robot (`robots/surveyed.toml`, 364 surveyed tags
/// with arbitrary ids) tracks its circle on the map's fixes, and its HIL
/// configuration announces the map, whose chunks carry every tag.
#[test]
fn the_surveyed_robot_tracks_on_its_tag_map() {
    let scenario = Scenario::from_file(&robots().join("circle_surveyed.toml")).unwrap();
    assert_eq!(scenario.floor_tags.len(), 364);
    let result = run(&scenario, |_, _| {}).unwrap();
    let rfid = result.summary.rfid.unwrap();
    assert!(rfid.frames_ok > 1000, "{} frames", rfid.frames_ok);
    assert_eq!(rfid.unknown_tags, 0);
    assert_eq!(result.summary.floor_tags, Some(364));
    // Tracking after the transient within 1 cm (measured: 4.5 mm rms).
    assert!(
        result.summary.rms_error_m < 0.01,
        "{}",
        result.summary.rms_error_m
    );
    // Under HIL the map follows `Configure` in chunks (host-tests/tests/
    // hil.rs runs it through the firmware).
    let setup = scenario.validate().unwrap();
    let configure = firmware_sim::simulation::hil_configuration(&setup).unwrap();
    assert_eq!(configure.floor, wmr_link::FloorSpec::Map { tags: 364 });
    let chunks = firmware_sim::simulation::hil_map_chunks(&setup).unwrap();
    assert_eq!(chunks.iter().map(|c| c.tags.len()).sum::<usize>(), 364);
}

/// Reader faults are the experiment's. A scenario naming its
/// robot keeps `position`'s fault keys, and they change the counters
/// exactly as in the same scenario with the robot written inline
/// (`figure_eight_rfid_full_stack`): same records, same reader and core
/// counters, bit for bit, and not those of the run without faults.
#[test]
fn reader_faults_in_a_scenario_naming_its_robot_are_kept() {
    let faults = "\n[position]\nkind = \"reader\"\ncorrupt_byte_probability = 0.01\n\
                  drop_frame_probability = 0.2\nseed = 7\n";
    let text = std::fs::read_to_string(robots().join("figure_eight.toml")).unwrap();
    let mut named = Scenario::from_toml_str_in(&(text.clone() + faults), Some(&robots())).unwrap();
    let mut clean = Scenario::from_toml_str_in(&text, Some(&robots())).unwrap();
    let mut inline = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
    let firmware_sim::scenario::PositionSpec::Reader {
        corrupt_byte_probability,
        drop_frame_probability,
        seed,
        ..
    } = &mut inline.position
    else {
        panic!("a reader")
    };
    (*corrupt_byte_probability, *drop_frame_probability, *seed) = (0.01, 0.2, 7);
    for s in [&mut named, &mut clean, &mut inline] {
        s.duration_s = 60.0;
        s.transient_s = 10.0;
    }
    assert_eq!(named.position, inline.position);
    let (a, b, c) = (
        run(&named, |_, _| {}).unwrap(),
        run(&inline, |_, _| {}).unwrap(),
        run(&clean, |_, _| {}).unwrap(),
    );
    let (ra, rb, rc) = (
        a.summary.rfid.unwrap(),
        b.summary.rfid.unwrap(),
        c.summary.rfid.unwrap(),
    );
    assert_eq!(ra, rb);
    assert!(a.records == b.records, "the records differ");
    // The faults did something: frames dropped, bytes corrupted, bad
    // checksums, none of which the clean run has.
    assert!(ra.reader.frames_dropped > 100, "{ra:?}");
    assert!(ra.reader.bytes_corrupted > 100, "{ra:?}");
    assert!(ra.bad_checksum + ra.malformed > 0, "{ra:?}");
    assert_eq!(
        (
            rc.reader.frames_dropped,
            rc.reader.bytes_corrupted,
            rc.bad_checksum
        ),
        (0, 0, 0)
    );
    assert!(ra.frames_ok < rc.frames_ok);
}

/// The fusion EKF on a surveyed floor with gaps: `robots/surveyed.toml`
/// on every second tag of its map (183 tags, with the one it starts on),
/// its range reader leaving gaps of up to ~25 cm between reads. Paper
/// 001's observer with the robot's 0.5 s fix timeout stops in the gaps
/// (failsafe) and loses the circle; with the timeout raised to 30 s it
/// tracks, with no failsafe left to speak of. The fusion EKF, its failsafe
/// on 1 m driven without a tag, tracks within 2 cm rms and better than the
/// observer: on a tag map it takes each pass over a tag as one
/// measurement of where the antenna entered the tag's read disc, which
/// needs no grid.
#[test]
fn the_fusion_estimator_tracks_on_a_sparse_tag_map() {
    let dir = temp_dir("sparse-map");
    let csv = std::fs::read_to_string(robots().join("surveyed_tags.csv")).unwrap();
    let mut sparse = String::new();
    let mut row = 0;
    for line in csv.lines() {
        let fields: Vec<&str> = line.split(',').collect();
        let tag = match fields[..] {
            [id, x, y] if id.starts_with("0x") => Some((x, y)),
            _ => None,
        };
        let keep = tag.is_none_or(|(x, y)| {
            let (x, y): (f64, f64) = (x.parse().unwrap(), y.parse().unwrap());
            row += 1;
            // Every second tag, and the one under the start (1.5, 0).
            row % 2 == 1 || (x - 1.5).hypot(y) < 0.1
        });
        if keep {
            sparse += line;
            sparse.push('\n');
        }
    }
    std::fs::write(dir.join("sparse_tags.csv"), sparse).unwrap();
    let robot = std::fs::read_to_string(robots().join("surveyed.toml"))
        .unwrap()
        .replace("surveyed_tags.csv", "sparse_tags.csv");
    let scenario = std::fs::read_to_string(robots().join("circle_surveyed.toml")).unwrap();
    let run_with = |robot: String| {
        std::fs::write(dir.join("surveyed.toml"), robot).unwrap();
        std::fs::write(dir.join("circle.toml"), &scenario).unwrap();
        let scenario = Scenario::from_file(&dir.join("circle.toml")).unwrap();
        assert_eq!(scenario.floor_tags.len(), 183);
        let result = run(&scenario, |_, _| {}).unwrap();
        assert_eq!(result.summary.rfid.unwrap().unknown_tags, 0);
        result.summary
    };
    let observer = run_with(robot.clone());
    let observer_30_s = run_with(robot.replace("fix_timeout_s = 0.5", "fix_timeout_s = 30.0"));
    let fusion = run_with(robot.replace(
        "[observer]",
        "[estimator.fusion]\nmax_blind_distance_m = 1.0\nwheel_variance_per_m = 3e-5\n\
         scale_prior = 4e-4\n\n[observer]",
    ));
    for (name, s) in [
        ("observer", &observer),
        ("observer, 30 s timeout", &observer_30_s),
        ("fusion EKF", &fusion),
    ] {
        eprintln!(
            "{name}: max {:.4} / mean {:.4} / rms {:.4} m after 30 s, failsafe entries {}",
            s.max_error_m,
            s.mean_error_m,
            s.rms_error_m,
            s.tracker.as_ref().unwrap().failsafe_entries
        );
    }
    assert!(observer.tracker.unwrap().failsafe_entries > 0);
    assert!(observer.rms_error_m > 0.5, "{}", observer.rms_error_m);
    assert_eq!(observer_30_s.tracker.as_ref().unwrap().failsafe_entries, 0);
    assert_eq!(fusion.tracker.as_ref().unwrap().failsafe_entries, 0);
    // Measured: 0.0163 m (observer with 30 s: 0.0303 m).
    assert!(fusion.rms_error_m < 0.02, "{}", fusion.rms_error_m);
    assert!(fusion.rms_error_m < observer_30_s.rms_error_m);
    assert!(fusion.max_error_m < observer_30_s.max_error_m);
}

/// `firmware-sim hil` records telemetry every `telemetry.every_ticks` of
/// the scenario's robot unless `--telemetry-every` says otherwise; without
/// a robot (or `[telemetry]`), every tick.
#[test]
fn hil_telemetry_defaults_to_the_robots() {
    use firmware_sim::hil::{DEFAULT_TELEMETRY_EVERY_TICKS, default_telemetry_every_ticks};
    let named = Scenario::from_file(&robots().join("figure_eight.toml")).unwrap();
    assert_eq!(default_telemetry_every_ticks(&named).unwrap(), 10);
    let text = std::fs::read_to_string(robots().join("example.toml")).unwrap();
    let dir = temp_dir("telemetry");
    std::fs::write(
        dir.join("example.toml"),
        text.replace("every_ticks = 10", "every_ticks = 4"),
    )
    .unwrap();
    let scenario = std::fs::read_to_string(robots().join("figure_eight.toml")).unwrap();
    let four = Scenario::from_toml_str_in(&scenario, Some(&dir)).unwrap();
    assert_eq!(default_telemetry_every_ticks(&four).unwrap(), 4);
    // A scenario may not set the robot's telemetry.
    let e =
        Scenario::from_toml_str_in(&(scenario + "\n[telemetry]\nevery_ticks = 2\n"), Some(&dir))
            .unwrap_err()
            .to_string();
    assert!(e.contains("`telemetry`") && e.contains("robot"), "{e}");
    let plain = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
    assert_eq!(
        default_telemetry_every_ticks(&plain).unwrap(),
        DEFAULT_TELEMETRY_EVERY_TICKS
    );
}

/// A scenario that names its robot refuses every robot table it also
/// gives, whatever its values: one equal to the defaults would otherwise be
/// ignored in silence while the robot's runs.
#[test]
fn a_robot_table_in_a_robot_named_scenario_is_refused_even_at_its_defaults() {
    let dir = temp_dir("robot-tables");
    std::fs::copy(robots().join("example.toml"), dir.join("example.toml")).unwrap();
    let scenario = std::fs::read_to_string(robots().join("figure_eight.toml")).unwrap();
    for (table, key) in [
        ("[controller]\nk1 = 0.11\n", "controller"),
        ("[plant]\nkind = \"unicycle\"\n", "plant"),
        ("period_s = 0.01\n", "period_s"),
    ] {
        // Top-level keys before the first table.
        let text = match table.starts_with('[') {
            true => format!("{scenario}\n{table}"),
            false => format!("{table}{scenario}"),
        };
        let file = dir.join("scenario.toml");
        std::fs::write(&file, text).unwrap();
        let e = Scenario::from_file(&file).unwrap_err();
        assert_eq!(e.field(), Some(key), "{e}");
        assert!(e.to_string().contains("sets it: remove it"), "{e}");
    }
}

/// A robot file that cannot be read is named as a robot file, with the
/// scenario key that named it.
#[test]
fn a_missing_robot_file_is_named_with_who_named_it() {
    let dir = temp_dir("missing-robot");
    let scenario = std::fs::read_to_string(robots().join("figure_eight.toml"))
        .unwrap()
        .replace("robot = \"example.toml\"", "robot = \"nope.toml\"");
    let file = dir.join("scenario.toml");
    std::fs::write(&file, scenario).unwrap();
    let e = Scenario::from_file(&file).unwrap_err().to_string();
    assert!(e.starts_with("cannot read robot file "), "{e}");
    assert!(
        e.contains("nope.toml, named by the scenario's `robot = \"nope.toml\"`"),
        "{e}"
    );
}
