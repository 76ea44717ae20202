//! Sweeps through the library and the CLI.

mod common;
use common::{sim, stdout_of_success};

use firmware_sim::sweep::output::runs_csv;
use firmware_sim::sweep::{SweepOptions, plan_of, run_sweep, run_variation};
use firmware_sim::{Scenario, run};

/// The RFID figure-eight, 60 s, varying every field that applies.
fn noisy_rfid() -> Scenario {
    let text = format!(
        "{}\n[sweep]\nobserver_start = \"unit_disc\"\nposition_noise_std_m = [0.0, 0.02]\n\
         read_miss_probability = [0.0, 0.3]\nconverge_hold_s = 5.0\n",
        firmware_sim::scenario::embedded_source("figure_eight_rfid").unwrap()
    )
    .replace("duration_s = 480.0", "duration_s = 60.0")
    .replace("transient_s = 100.0", "transient_s = 30.0");
    Scenario::from_toml_str(&text).unwrap()
}

#[test]
fn a_sweep_is_reproducible_run_by_run() {
    let s = noisy_rfid();
    let options = SweepOptions {
        runs: 6,
        seed: 3,
        threads: 2,
    };
    let result = run_sweep(&s, &options, &|| {}).unwrap();
    assert_eq!(result.rows.len(), 6);
    assert_eq!(result.summary.runs, 6);
    let (_, plan) = plan_of(&s).unwrap();
    for row in &result.rows {
        assert!(row.position_noise_std_m.unwrap() <= 0.02);
        assert!(row.read_miss_probability.unwrap() <= 0.3);
        let (concrete, rerun, again) = run_variation(&s, &plan, 3, row.index).unwrap();
        assert_eq!(&again, row);
        assert_eq!(rerun.summary.final_error_m, row.final_error_m);
        // The concrete scenario file reproduces it too.
        let reparsed = Scenario::from_toml_str(&concrete.to_toml_string().unwrap()).unwrap();
        let by_file = run(&reparsed, |_, _| {}).unwrap();
        assert_eq!(by_file.records, rerun.records);
    }
    let csv = String::from_utf8(runs_csv(&result.rows).unwrap()).unwrap();
    assert_eq!(csv.lines().count(), 7);
    assert!(csv.starts_with("index,seed,start_x_m"), "{csv}");
}

#[test]
fn cli_sweep_writes_its_files_and_reruns_one_case() {
    let dir = tempfile::tempdir().unwrap();
    let out = sim()
        .args([
            "sweep",
            "figure_eight_rfid",
            "--runs",
            "4",
            "--seed",
            "5",
            "--duration-s",
            "60",
            "--out",
        ])
        .arg(dir.path().join("s"))
        .output()
        .unwrap();
    let stdout = stdout_of_success(&out);
    assert!(stdout.contains("| `figure_eight_rfid` |"), "{stdout}");
    for f in [
        "runs.csv",
        "summary.json",
        "table.md",
        "error_hist.png",
        "error_vs_distance.png",
    ] {
        assert!(dir.path().join("s").join(f).is_file(), "{f}");
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("s/summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["runs"], 4);
    assert_eq!(summary["seed"], 5);

    let out = sim()
        .args([
            "sweep",
            "figure_eight_rfid",
            "--seed",
            "5",
            "--rerun",
            "2",
            "--duration-s",
            "60",
            "--no-plot",
            "--out",
        ])
        .arg(dir.path().join("r"))
        .output()
        .unwrap();
    assert!(stdout_of_success(&out).contains("index 2, seed 5"));
    let csv = std::fs::read_to_string(dir.path().join("s/runs.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let column = header.iter().position(|h| *h == "final_error_m").unwrap();
    let row2: Vec<&str> = csv.lines().nth(3).unwrap().split(',').collect();
    assert_eq!(row2[0], "2");
    let final_error: f64 = row2[column].parse().unwrap();
    let rerun: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("r/summary.json")).unwrap())
            .unwrap();
    assert_eq!(rerun["final_error_m"].as_f64().unwrap(), final_error);
    assert!(dir.path().join("r/scenario.toml").is_file());
    assert!(dir.path().join("r/run.csv").is_file());
}

#[test]
fn cli_refuses_a_sweep_field_that_cannot_apply() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    std::fs::write(
        &path,
        "name = \"bad\"\nduration_s = 10.0\n[reference]\nkind = \"figure_eight\"\n\
         [sweep]\nencoder_counts_per_rev = [512, 1024]\n",
    )
    .unwrap();
    let out = sim().arg("sweep").arg(&path).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("sweep.encoder_counts_per_rev") && err.contains("diff_drive"),
        "{err}"
    );
}
