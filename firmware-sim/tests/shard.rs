//! Sharded sweeps (`sweep … --shard K/N`) and their merge
//! (`sweep-merge`): the merge writes the unsharded sweep's files byte for
//! byte, and refuses what is not one whole sweep.

mod common;
use common::{sim, stdout_of_success};

use std::path::{Path, PathBuf};
use std::process::Output;

/// The sweep every refusal case starts from: 5 runs of 2 s, seed 1.
const BASE: [&str; 6] = ["--runs", "5", "--duration-s", "2", "--seed", "1"];

/// `firmware-sim sweep` with `args`, into `out`.
fn sweep(args: &[&str], out: &Path) -> Output {
    sim()
        .arg("sweep")
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

/// `firmware-sim sweep-merge DIRS --out out --no-plot`.
fn merge(dirs: &[&Path], out: &Path) -> Output {
    sim()
        .arg("sweep-merge")
        .args(dirs)
        .arg("--out")
        .arg(out)
        .arg("--no-plot")
        .output()
        .unwrap()
}

/// The standard error of a command that must have failed.
fn stderr_of_failure(out: &Output) -> String {
    assert!(
        !out.status.success(),
        "succeeded: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Asserts the files `names` under `a` and `b` have the same bytes.
fn assert_same_files(a: &Path, b: &Path, names: &[&str]) {
    for name in names {
        let (x, y) = (a.join(name), b.join(name));
        let x = std::fs::read(&x).unwrap_or_else(|e| panic!("{}: {e}", x.display()));
        let y = std::fs::read(&y).unwrap_or_else(|e| panic!("{}: {e}", y.display()));
        assert!(
            x == y,
            "{name} differs between {} and {}",
            a.display(),
            b.display()
        );
    }
}

#[test]
fn three_shards_merge_into_the_unsharded_files_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = [
        "figure_eight_rfid",
        "--runs",
        "10",
        "--seed",
        "4",
        "--duration-s",
        "60",
        "--no-plot",
    ];
    stdout_of_success(&sweep(&args, &d.join("whole")));
    // Last shard first: the order they run in does not matter.
    let shards: Vec<PathBuf> = (0..3).map(|k| d.join(format!("shard-{k}"))).collect();
    for k in [2, 0, 1] {
        let spec = format!("{k}/3");
        let text = stdout_of_success(&sweep(
            &[&args[..], &["--shard", &spec]].concat(),
            &shards[k],
        ));
        assert!(
            text.contains(&format!("shard         {k}/3: run indices")),
            "{text}"
        );
        // A shard does not pass for the sweep.
        assert!(!text.contains("| scenario |"), "{text}");
        for f in ["summary.json", "table.md", "error_hist.png"] {
            assert!(!shards[k].join(f).exists(), "shard {k} wrote {f}");
        }
    }
    // Shard 1 of 10 runs / 3 is runs 3..6.
    let csv = std::fs::read_to_string(shards[1].join("runs.csv")).unwrap();
    let first: Vec<&str> = csv.lines().skip(1).map(|l| &l[..2]).collect();
    assert_eq!(first, ["3,", "4,", "5,"], "{csv}");
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(shards[1].join("shard.json")).unwrap())
            .unwrap();
    assert_eq!(manifest["shard"], 1);
    assert_eq!(manifest["shards"], 3);
    assert_eq!(manifest["runs"], 10);
    assert_eq!(manifest["indices"]["start"], 3);
    assert_eq!(manifest["indices"]["end"], 6);

    // Any order on the command line.
    let text = stdout_of_success(&merge(
        &[&shards[1], &shards[2], &shards[0]],
        &d.join("merged"),
    ));
    assert!(text.contains("merged        3 shards"), "{text}");
    assert!(text.contains("| `figure_eight_rfid` |"), "{text}");
    assert_same_files(
        &d.join("whole"),
        &d.join("merged"),
        &["runs.csv", "summary.json", "table.md"],
    );
    // `--no-plot` is honoured.
    assert!(!d.join("merged/error_hist.png").exists());
    // The comparison is of a sweep with both outcomes, not an empty one.
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("merged/summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["runs"], 10);
    let converged = summary["converged"].as_u64().unwrap();
    assert!(0 < converged && converged < 10, "{summary}");
}

#[test]
fn several_scenarios_and_an_empty_shard_merge_with_the_plots() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = [
        "figure_eight_rfid",
        "figure_eight_rfid_full_stack",
        "--runs",
        "4",
        "--seed",
        "2",
        "--duration-s",
        "30",
    ];
    stdout_of_success(&sweep(&args, &d.join("whole")));
    // 5 shards of 4 runs: shard 0 has none.
    let shards: Vec<PathBuf> = (0..5).map(|k| d.join(format!("shard-{k}"))).collect();
    for (k, shard) in shards.iter().enumerate() {
        let spec = format!("{k}/5");
        stdout_of_success(&sweep(&[&args[..], &["--shard", &spec]].concat(), shard));
        assert!(
            shard
                .join("figure_eight_rfid_full_stack/runs.csv")
                .is_file()
        );
        assert!(!shard.join("table.md").exists());
    }
    // The empty shard's runs.csv is the header alone: the whole sweep's
    // first line.
    let empty = std::fs::read_to_string(shards[0].join("figure_eight_rfid/runs.csv")).unwrap();
    let whole =
        std::fs::read_to_string(d.join("whole").join("figure_eight_rfid/runs.csv")).unwrap();
    assert_eq!(empty.lines().count(), 1, "{empty}");
    assert_eq!(empty.lines().next(), whole.lines().next());
    let dirs: Vec<&Path> = shards.iter().map(PathBuf::as_path).collect();
    let out = sim()
        .arg("sweep-merge")
        .args(&dirs)
        .arg("--out")
        .arg(d.join("merged"))
        .output()
        .unwrap();
    let text = stdout_of_success(&out);
    assert!(
        text.contains("| `figure_eight_rfid_full_stack` |"),
        "{text}"
    );
    assert_same_files(&d.join("whole"), &d.join("merged"), &["table.md"]);
    for name in ["figure_eight_rfid", "figure_eight_rfid_full_stack"] {
        assert_same_files(
            &d.join("whole").join(name),
            &d.join("merged").join(name),
            &[
                "runs.csv",
                "summary.json",
                "table.md",
                // Rendered again from the merged rows: the same image.
                "error_hist.png",
                "error_vs_distance.png",
            ],
        );
    }
}

#[test]
fn shard_k_of_n_is_refused_unless_k_counts_from_0_below_n() {
    let dir = tempfile::tempdir().unwrap();
    for (spec, says) in [
        ("3/3", "must be below N (0/3 … 2/3)"),
        ("1/0", "at least 1"),
        ("1", "expected K/N"),
        ("one/3", "expected K/N"),
    ] {
        let err = stderr_of_failure(&sweep(
            &[&BASE[..], &["--shard", spec]].concat(),
            dir.path(),
        ));
        assert!(err.contains(says), "{spec}: {err}");
    }
    let err = stderr_of_failure(&sweep(
        &[&BASE[..], &["--shard", "0/2", "--rerun", "1"]].concat(),
        dir.path(),
    ));
    assert!(err.contains("cannot be used with"), "{err}");
    // Two scenarios of one name would share DIR/<name>/.
    let twice = ["figure_eight_rfid", "figure_eight_rfid"];
    let err = stderr_of_failure(&sweep(
        &[&twice[..], &BASE[..], &["--shard", "0/2"]].concat(),
        &dir.path().join("twice"),
    ));
    assert!(
        err.contains("two scenarios are named `figure_eight_rfid`"),
        "{err}"
    );
    // Nor does a shard go where a whole sweep is.
    stdout_of_success(&sweep(&BASE, &dir.path().join("whole")));
    let err = stderr_of_failure(&sweep(
        &[&BASE[..], &["--shard", "0/2"]].concat(),
        &dir.path().join("whole"),
    ));
    assert!(err.contains("holds a whole sweep"), "{err}");
}

/// Shards 0/3, 1/3 and 2/3 of [`BASE`] in `d/a0`, `d/a1`, `d/a2`.
fn base_shards(d: &Path) -> Vec<PathBuf> {
    (0..3)
        .map(|k| {
            let out = d.join(format!("a{k}"));
            let spec = format!("{k}/3");
            stdout_of_success(&sweep(&[&BASE[..], &["--shard", &spec]].concat(), &out));
            out
        })
        .collect()
}

#[test]
fn merge_refuses_shards_of_other_sweeps_naming_the_directory_and_the_difference() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a = base_shards(d);
    // Shard 1/3 of sweeps that differ in one thing each.
    let gains = d.join("gains.toml");
    std::fs::write(
        &gains,
        firmware_sim::scenario::embedded_source("figure_eight_rfid")
            .unwrap()
            .replace("k3 = 0.1", "k3 = 0.2"),
    )
    .unwrap();
    let gains = gains.to_string_lossy().into_owned();
    let cases: [(&str, Vec<&str>, &str); 6] = [
        (
            "seed",
            vec!["--runs", "5", "--duration-s", "2", "--seed", "2"],
            "seed 2, not 1",
        ),
        (
            "runs",
            vec!["--runs", "6", "--duration-s", "2", "--seed", "1"],
            "runs 6, not 5",
        ),
        (
            "duration",
            vec!["--runs", "5", "--duration-s", "3", "--seed", "1"],
            "--duration-s 3 s, not 2 s",
        ),
        (
            "scenario",
            [&["figure_eight_exact"], &BASE[..]].concat(),
            "scenarios `figure_eight_exact`, not `figure_eight_rfid`",
        ),
        (
            "content",
            [&[gains.as_str()], &BASE[..]].concat(),
            "scenario `figure_eight_rfid` has the same name but other content",
        ),
        ("count", BASE.to_vec(), "shard count N 4, not 3"),
    ];
    for (name, args, says) in cases {
        let other = d.join(name);
        let spec = if name == "count" { "1/4" } else { "1/3" };
        stdout_of_success(&sweep(&[&args[..], &["--shard", spec]].concat(), &other));
        let err = stderr_of_failure(&merge(&[&a[0], &other, &a[2]], &d.join("m")));
        assert!(
            err.contains(&format!("{} is a shard of another sweep", other.display()))
                && err.contains(says),
            "{name}: {err}"
        );
        assert!(!d.join("m").exists(), "{name}: merged anyway");
    }
}

#[test]
fn merge_refuses_missing_duplicated_unfinished_and_altered_shards() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a = base_shards(d);
    let out = d.join("m");

    let err = stderr_of_failure(&merge(&[&a[0], &a[2]], &out));
    assert!(
        err.contains("missing shard 1/3 of the 3 (2 of the 5 runs)"),
        "{err}"
    );
    let err = stderr_of_failure(&merge(&[&a[2]], &out));
    assert!(err.contains("missing shards 0/3, 1/3"), "{err}");

    let err = stderr_of_failure(&merge(&[&a[0], &a[1], &a[2], &a[1]], &out));
    assert!(
        err.contains(&format!("{} is given twice", a[1].display())),
        "{err}"
    );
    let copy = d.join("copy");
    std::fs::create_dir(&copy).unwrap();
    for f in ["runs.csv", "shard.json"] {
        std::fs::copy(a[1].join(f), copy.join(f)).unwrap();
    }
    let err = stderr_of_failure(&merge(&[&a[0], &a[1], &a[2], &copy], &out));
    assert!(err.contains("are both shard 1/3"), "{err}");

    // A shard that did not finish has no shard.json.
    let unfinished = d.join("unfinished");
    std::fs::create_dir(&unfinished).unwrap();
    std::fs::copy(a[1].join("runs.csv"), unfinished.join("runs.csv")).unwrap();
    let err = stderr_of_failure(&merge(&[&a[0], &unfinished, &a[2]], &out));
    assert!(
        err.contains(&format!("{}: no shard.json", unfinished.display())),
        "{err}"
    );

    // A row gone from runs.csv, or one number rewritten.
    let csv = std::fs::read_to_string(copy.join("runs.csv")).unwrap();
    let mut lines: Vec<&str> = csv.lines().collect();
    lines.pop();
    std::fs::write(copy.join("runs.csv"), lines.join("\n") + "\n").unwrap();
    let err = stderr_of_failure(&merge(&[&a[0], &copy, &a[2]], &out));
    assert!(
        err.contains("runs.csv: run indices 1..2 are not the indices of shard 1/3"),
        "{err}"
    );
    // Seed `01` reads as 1, but is not what the shard wrote.
    let edited = csv.replacen("\n1,1,", "\n1,01,", 1);
    assert_ne!(edited, csv);
    std::fs::write(copy.join("runs.csv"), edited).unwrap();
    let err = stderr_of_failure(&merge(&[&a[0], &copy, &a[2]], &out));
    assert!(
        err.contains("runs.csv: does not read back to the same bytes"),
        "{err}"
    );
    assert!(!out.exists(), "merged anyway");

    // The merge does not write over a shard.
    let err = stderr_of_failure(&merge(&[&a[0], &a[1], &a[2]], &a[1]));
    assert!(
        err.contains(&format!("{} holds a shard.json", a[1].display())),
        "{err}"
    );
    assert!(!a[1].join("summary.json").exists());
    stdout_of_success(&merge(&[&a[0], &a[1], &a[2]], &out));
    assert!(out.join("summary.json").is_file());
}
