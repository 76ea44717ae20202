//! The command-line interface.

mod common;
use common::{sim, stdout_of_success};

#[test]
fn bad_scenario_file_fails_with_the_field_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    std::fs::write(
        &path,
        "name = \"bad\"\nduration_s = 10.0\n[reference]\nkind = \"figure_eight\"\n[observer]\ngain_per_m = -1.0\n",
    )
    .unwrap();
    let out = sim()
        .arg("run")
        .arg(&path)
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("observer.gain_per_m"), "{err}");

    std::fs::write(&path, "name = \"bad\"\nduration_s = 10.0\nspeed = 3\n").unwrap();
    let out = sim().arg("run").arg(&path).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("speed") && err.contains("bad.toml"), "{err}");

    let out = sim().args(["run", "/nonexistent/x.toml"]).output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/x.toml"));
}

#[test]
fn run_writes_outputs_and_prints_the_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out = sim()
        .args([
            "run",
            "figure_eight_rfid",
            "--duration-s",
            "5",
            "--no-plot",
            "--out",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    let text = stdout_of_success(&out);
    assert!(
        text.contains("figure_eight_rfid") && text.contains("max"),
        "{text}"
    );
    assert!(dir.path().join("run.csv").exists());
    assert!(dir.path().join("summary.json").exists());
    assert!(!dir.path().join("run.png").exists());
}

/// `firmware-sim run` with no scenario: the default one (paper 001's RFID
/// figure-eight, 480 s), whole, with its plot, as a new user runs it first.
#[test]
fn the_default_scenario_runs_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let out = sim()
        .arg("run")
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    let text = stdout_of_success(&out);
    assert!(text.contains("figure_eight_rfid"), "{text}");
    let csv = std::fs::read_to_string(dir.path().join("run.csv")).unwrap();
    // A header and one record per 10 ms tick of the 480 s run.
    assert_eq!(csv.lines().count(), 1 + 48_000, "{}", csv.lines().count());
    assert!(dir.path().join("summary.json").exists());
    let png = std::fs::metadata(dir.path().join("run.png")).unwrap();
    assert!(png.len() > 10_000, "plot of {} B", png.len());
}

#[test]
fn scenarios_are_listed_and_shown() {
    let text = stdout_of_success(&sim().arg("scenarios").output().unwrap());
    for (name, _) in firmware_sim::EMBEDDED
        .iter()
        .chain(firmware_sim::slip::EMBEDDED_SLIP)
    {
        assert!(text.contains(name), "{text}");
    }
    let out = sim().args(["show", "figure_eight_exact"]).output().unwrap();
    assert!(stdout_of_success(&out).contains("gain_per_m = 4.0"));
    let out = sim().args(["show", "paper_004_torque"]).output().unwrap();
    assert!(stdout_of_success(&out).contains("controller = \"torque\""));
    let out = sim().args(["scenario-template", "nope"]).output().unwrap();
    assert!(!out.status.success());
}

/// `schema --slip` lists the slip scenario file's keys with their units
/// and defaults, `--json --slip` is its JSON Schema, `--robot` alone the
/// robot file's table, and `--robot --slip` is refused by name.
#[test]
fn schema_lists_the_slip_file_keys() {
    let table = stdout_of_success(&sim().args(["schema", "--slip"]).output().unwrap());
    for row in [
        "| `duration_s` |  | number > 0.0 | `60.0` | s |",
        "| `robot.wheel_radius_m` |  | number > 0.0 | `0.35` | m |",
        "| `reference.segments.v_m_s` | each `[[reference.segments]]` | number | required | m/s |",
        "| `slip.start_s` | each `[[slip]]` | number ≥ 0.0 | required | s |",
        "| `gains.k1` |  | number > 0.0 | `6.0` | 1/s |",
    ] {
        assert!(table.contains(row), "no `{row}` in\n{table}");
    }
    // The slip file's own keys, not the scenario file's.
    assert!(!table.contains("`reference.kind`"), "{table}");

    let json = stdout_of_success(&sim().args(["schema", "--json", "--slip"]).output().unwrap());
    let schema: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(schema["title"], "SlipScenario", "{json}");
    assert!(schema["properties"]["slip"].is_object(), "{json}");

    let robot = stdout_of_success(&sim().args(["schema", "--robot"]).output().unwrap());
    assert!(robot.contains("`plant.wheel_radius_m`"), "{robot}");
    // The robot table alone: no scenario-only key such as `transient_s`.
    assert!(!robot.contains("`transient_s`"), "{robot}");

    let out = sim()
        .args(["schema", "--robot", "--slip"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--slip") && err.contains("--robot"), "{err}");
}

/// `firmware-sim … | head`: a reader that closes the pipe early ends the
/// program quietly and successfully, for every subcommand that prints.
#[test]
fn a_closed_output_pipe_ends_quietly() {
    use std::process::Stdio;
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().to_string_lossy().into_owned();
    let shard_dir = dir.path().join("shard").to_string_lossy().into_owned();
    let merged_dir = dir.path().join("merged").to_string_lossy().into_owned();
    let short_sweep = ["sweep", "--runs", "2", "--duration-s", "1", "--no-plot"];
    let shard: Vec<&str> = [&short_sweep[..], &["--shard", "0/1", "--out", &shard_dir]].concat();
    let cases: [&[&str]; 6] = [
        &["scenarios"],
        &["schema", "--slip"],
        &["show", "figure_eight_rfid"],
        &[
            "run",
            "figure_eight_exact",
            "--duration-s",
            "1",
            "--no-plot",
            "--out",
            &out_dir,
        ],
        // Each writes its files before it prints: the merge reads the shard.
        &shard,
        &["sweep-merge", &shard_dir, "--no-plot", "--out", &merged_dir],
    ];
    for args in cases {
        let mut child = sim()
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Closed before the program writes: its first write meets EPIPE.
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{args:?}: {:?} {err}", out.status);
        assert!(
            !err.contains("panicked") && !err.contains("Broken pipe"),
            "{args:?}: {err}"
        );
    }
    assert!(dir.path().join("merged/summary.json").is_file());
}
