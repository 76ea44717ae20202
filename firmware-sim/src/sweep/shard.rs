//! Sweeps beyond one machine: each machine runs one shard of the run
//! indices (`firmware-sim sweep … --shard K/N`), and
//! `firmware-sim sweep-merge` puts the shards back together into the files
//! of the unsharded sweep, byte for byte.
//!
//! # Shards
//! Shard `K/N` counts `K` from 0 (`0 ≤ K < N`), as Slurm's
//! `SLURM_ARRAY_TASK_ID` and Kubernetes' `JOB_COMPLETION_INDEX` do. Of a
//! sweep of `R` runs it runs the contiguous block of indices
//! `⌊K·R/N⌋ .. ⌊(K+1)·R/N⌋` (end excluded; block sizes differ by one at
//! most, and a shard of a sweep with fewer runs than shards may be empty).
//! Run `i` depends on the scenario, the seed and `i` only (see the
//! [module docs](super#seeds)), so a shard's rows are exactly the rows the
//! unsharded sweep has for the same indices.
//!
//! # A shard's directory
//! `runs.csv` of its runs (the unsharded sweep's format and rows), and
//! [`MANIFEST`] (`shard.json`, a [`ShardManifest`]): what the shard is a
//! share of (the concrete scenarios as swept, the seed, the number of runs,
//! the `--duration-s` override, `K/N`, its indices), written last, so a
//! shard that did not finish has none. With several scenarios, as for
//! `sweep`, each scenario's `runs.csv` is in `DIR/<name>/` and `shard.json`
//! in `DIR`. A shard writes no `summary.json`, `table.md` or plots: its
//! figures would not be the sweep's.
//!
//! # Merging
//! [`merge_shards`] reads every shard, refuses shards of different sweeps
//! (scenario, seed, runs, duration, shard count, version), duplicated or
//! missing shards and rows that are not the manifest's indices, naming the
//! directory and the reason, and summarizes the rows in index order with
//! the unsharded sweep's own code ([`summarize`]).

use std::collections::BTreeMap;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use anyhow::{Context as _, bail, ensure};
use serde::{Deserialize, Serialize};

use super::output::{runs_csv, scenario_dir};
use super::{SweepResult, SweepRun, summarize};
use crate::scenario::Scenario;

/// The name of a shard's manifest.
pub const MANIFEST: &str = "shard.json";

/// The manifest's `format`: what reads it checks it first.
pub const FORMAT: &str = "firmware-sim sweep shard 1";

/// The version of this program, which a shard records: a merge takes only
/// shards of the version that merges them.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

/// Shard `K` of `N`, `K` counted from 0 (see the [module docs](self)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Shard {
    index: u64,
    count: u64,
}

impl Shard {
    /// Shard `index` of `count`.
    ///
    /// # Errors
    /// `count` is 0, or `index` is not below it.
    pub fn new(index: u64, count: u64) -> Result<Self, String> {
        if count == 0 {
            return Err("the number of shards N must be at least 1".to_owned());
        }
        if index >= count {
            return Err(format!(
                "shard {index}/{count} does not exist: K counts from 0 and must be below N \
                 (0/{count} … {}/{count}), as Slurm's SLURM_ARRAY_TASK_ID and Kubernetes' \
                 JOB_COMPLETION_INDEX do",
                count - 1
            ));
        }
        Ok(Self { index, count })
    }

    /// `K`, from 0.
    #[must_use]
    pub fn index(&self) -> u64 {
        self.index
    }

    /// `N`.
    #[must_use]
    pub fn count(&self) -> u64 {
        self.count
    }

    /// This shard's run indices in a sweep of `runs` runs:
    /// `⌊K·runs/N⌋ .. ⌊(K+1)·runs/N⌋`.
    #[must_use]
    pub fn indices(&self, runs: u64) -> Range<u64> {
        let bound = |k: u64| {
            // At most `runs`, so it fits back into u64.
            u64::try_from(u128::from(k) * u128::from(runs) / u128::from(self.count)).unwrap_or(runs)
        };
        bound(self.index)..bound(self.index + 1)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = String;

    /// `K/N`, e.g. `0/4`.
    fn from_str(s: &str) -> Result<Self, String> {
        let form = || {
            format!("expected K/N, e.g. 0/4 for the first of 4 shards (K counts from 0), got `{s}`")
        };
        let (k, n) = s.split_once('/').ok_or_else(form)?;
        let k = k.trim().parse().map_err(|_| form())?;
        let n = n.trim().parse().map_err(|_| form())?;
        Self::new(k, n)
    }
}

/// What a shard is a share of (`shard.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardManifest {
    /// [`FORMAT`].
    pub format: String,
    /// The version of `firmware-sim` that ran the shard ([`VERSION`]).
    pub firmware_sim_version: String,
    /// `K`, counted from 0.
    pub shard: u64,
    /// `N`.
    pub shards: u64,
    /// The sweep's seed `S`.
    pub seed: u64,
    /// The whole sweep's number of runs (`--runs`), not this shard's.
    pub runs: u64,
    /// The `--duration-s` override, s, if one was given (the scenarios
    /// below have it applied).
    pub duration_s: Option<f64>,
    /// The run indices this shard ran (`end` excluded).
    pub indices: Range<u64>,
    /// The swept scenarios, in the order given (the table's row order).
    pub scenarios: Vec<ShardScenario>,
}

/// One swept scenario of a shard.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardScenario {
    /// Its name (its directory, with several scenarios).
    pub name: String,
    /// The scenario as swept (after `--duration-s`), as TOML: a merge
    /// summarizes with it, and refuses shards where it differs.
    pub toml: String,
}

impl ShardManifest {
    /// The manifest of `shard` of a sweep of `scenarios` (as swept, after
    /// any `duration_s` override) with `runs` runs and seed `seed`.
    ///
    /// # Errors
    /// A scenario that does not survive the trip through TOML unchanged
    /// (a bug: a merge could not reproduce its summary).
    pub fn new(
        scenarios: &[Scenario],
        shard: Shard,
        runs: u64,
        seed: u64,
        duration_s: Option<f64>,
    ) -> anyhow::Result<Self> {
        let scenarios = scenarios
            .iter()
            .map(|s| {
                let toml = s.to_toml_string()?;
                let again = Scenario::from_toml_str(&toml)?;
                ensure!(
                    again == *s,
                    "scenario `{}` does not read back from TOML unchanged, so a merge could \
                     not reproduce its summary (a bug)",
                    s.name
                );
                Ok(ShardScenario {
                    name: s.name.clone(),
                    toml,
                })
            })
            .collect::<anyhow::Result<_>>()?;
        Ok(Self {
            format: FORMAT.to_owned(),
            firmware_sim_version: VERSION.to_owned(),
            shard: shard.index(),
            shards: shard.count(),
            seed,
            runs,
            duration_s,
            indices: shard.indices(runs),
            scenarios,
        })
    }

    /// `K/N` (checked when read).
    fn shard(&self) -> anyhow::Result<Shard> {
        Shard::new(self.shard, self.shards).map_err(anyhow::Error::msg)
    }

    fn names(&self) -> Vec<&str> {
        self.scenarios.iter().map(|s| s.name.as_str()).collect()
    }
}

/// The files [`write_shard`] wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ShardFiles {
    /// Each scenario's `runs.csv`, in the manifest's order.
    pub runs_csv: Vec<PathBuf>,
    /// `shard.json`.
    pub manifest: PathBuf,
}

/// Writes a shard into `dir`: each scenario's `runs.csv` (`results` in the
/// manifest's order), then `shard.json`, each whole (through a temporary
/// file). A `shard.json` already there is removed first, so a shard
/// interrupted while rewriting has none.
///
/// # Errors
/// `results` that are not the manifest's scenarios and indices; a `dir`
/// that holds the `summary.json` or `table.md` of a whole sweep (a shard
/// beside them would be taken for one); any I/O error, with its file.
pub fn write_shard(
    dir: &Path,
    manifest: &ShardManifest,
    results: &[SweepResult],
) -> anyhow::Result<ShardFiles> {
    ensure!(
        results.len() == manifest.scenarios.len(),
        "{} results for {} scenarios",
        results.len(),
        manifest.scenarios.len()
    );
    let count = results.len();
    let dirs: Vec<PathBuf> = manifest
        .scenarios
        .iter()
        .map(|s| scenario_dir(dir, count, &s.name))
        .collect();
    let mut whole = vec![dir.join("table.md")];
    whole.extend(dirs.iter().map(|d| d.join("summary.json")));
    if let Some(found) = whole.iter().find(|p| p.exists()) {
        bail!(
            "{} exists: {} holds a whole sweep (or a merge), and a shard written beside it \
             would be taken for one; give the shard a directory of its own (--out)",
            found.display(),
            dir.display()
        );
    }
    let manifest_path = dir.join(MANIFEST);
    match std::fs::remove_file(&manifest_path) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => {
            return Err(e).with_context(|| format!("removing {}", manifest_path.display()));
        }
    }
    let mut runs_csv_paths = Vec::new();
    for ((scenario, result), scenario_dir) in manifest.scenarios.iter().zip(results).zip(&dirs) {
        ensure!(
            result.summary.scenario == scenario.name
                && result
                    .rows
                    .iter()
                    .map(|r| r.index)
                    .eq(manifest.indices.clone()),
            "the result of `{}` is not the manifest's scenario and indices",
            scenario.name
        );
        std::fs::create_dir_all(scenario_dir)
            .with_context(|| format!("creating {}", scenario_dir.display()))?;
        let path = scenario_dir.join("runs.csv");
        write_whole(&path, &runs_csv(&result.rows)?)?;
        runs_csv_paths.push(path);
    }
    write_whole(
        &manifest_path,
        (serde_json::to_string_pretty(manifest)? + "\n").as_bytes(),
    )?;
    Ok(ShardFiles {
        runs_csv: runs_csv_paths,
        manifest: manifest_path,
    })
}

/// Writes `bytes` to a temporary file beside `path`, then renames it to
/// `path`: a reader sees the old file or the whole new one (a shard
/// retried while another copy of it still runs writes the same bytes).
fn write_whole(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
    std::fs::write(&tmp, bytes).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path)
        .with_context(|| format!("renaming {} to {}", tmp.display(), path.display()))
}

/// A shard as read back: its manifest and each scenario's rows.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadShard {
    /// Its directory.
    pub dir: PathBuf,
    /// Its `shard.json`.
    pub manifest: ShardManifest,
    /// Each scenario's rows, in the manifest's order.
    pub rows: Vec<Vec<SweepRun>>,
}

/// Reads the shard in `dir` and checks it on its own: the manifest's
/// format, `K/N` and indices, and that each `runs.csv` holds exactly the
/// manifest's indices, in order, with its seed, and reads back to the
/// same bytes (so the merge summarizes exactly what the file says).
///
/// # Errors
/// What is missing or wrong, naming the file.
pub fn read_shard(dir: &Path) -> anyhow::Result<ReadShard> {
    let path = dir.join(MANIFEST);
    let text = match std::fs::read_to_string(&path) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => bail!(
            "{}: no {MANIFEST}: not a shard written by `firmware-sim sweep --shard K/N`, or \
             its shard did not finish ({MANIFEST} is written last)",
            dir.display()
        ),
        Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
    };
    let format: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}", path.display()))?;
    ensure!(
        format["format"] == FORMAT,
        "{}: format {}, expected \"{FORMAT}\"",
        path.display(),
        format["format"]
    );
    let manifest: ShardManifest =
        serde_json::from_str(&text).with_context(|| format!("{}", path.display()))?;
    let shard = manifest
        .shard()
        .with_context(|| format!("{}", path.display()))?;
    let expected = shard.indices(manifest.runs);
    ensure!(
        manifest.indices == expected,
        "{}: indices {:?}, but shard {shard} of {} runs is {expected:?}",
        path.display(),
        manifest.indices,
        manifest.runs
    );
    let names = manifest.names();
    ensure!(!names.is_empty(), "{}: no scenarios", path.display());
    if let Some(name) = names
        .iter()
        .enumerate()
        .find_map(|(i, n)| names[..i].contains(n).then_some(n))
    {
        bail!("{}: scenario `{name}` twice", path.display());
    }
    let mut rows = Vec::new();
    for scenario in &manifest.scenarios {
        let csv_path = scenario_dir(dir, manifest.scenarios.len(), &scenario.name).join("runs.csv");
        let bytes =
            std::fs::read(&csv_path).with_context(|| format!("reading {}", csv_path.display()))?;
        let these = csv::Reader::from_reader(bytes.as_slice())
            .deserialize()
            .collect::<Result<Vec<SweepRun>, _>>()
            .with_context(|| format!("{}", csv_path.display()))?;
        let indices: Vec<u64> = these.iter().map(|r| r.index).collect();
        ensure!(
            indices.iter().copied().eq(manifest.indices.clone()),
            "{}: run indices {} are not the indices of shard {shard} in {} ({:?})",
            csv_path.display(),
            describe_indices(&indices),
            path.display(),
            manifest.indices
        );
        if let Some(row) = these.iter().find(|r| r.seed != manifest.seed) {
            bail!(
                "{}: run {} has seed {}, but {} says {}",
                csv_path.display(),
                row.index,
                row.seed,
                path.display(),
                manifest.seed
            );
        }
        ensure!(
            runs_csv(&these)? == bytes,
            "{}: does not read back to the same bytes (edited by hand?); rerun shard {shard}",
            csv_path.display()
        );
        rows.push(these);
    }
    Ok(ReadShard {
        dir: dir.to_path_buf(),
        manifest,
        rows,
    })
}

/// `0..3` for `[0, 1, 2]`, else the list (`[]` when empty).
fn describe_indices(indices: &[u64]) -> String {
    match (indices.first(), indices.last()) {
        (Some(&a), Some(&b)) if indices.iter().copied().eq(a..=b) => format!("{a}..{}", b + 1),
        _ => format!("{indices:?}"),
    }
}

/// Shards merged into the sweep they are shares of.
#[derive(Debug, Clone, PartialEq)]
pub struct MergedSweep {
    /// One result per scenario, in the shards' order: what the unsharded
    /// sweep computes.
    pub results: Vec<SweepResult>,
    /// The shards' directories, by `K`.
    pub shards: Vec<PathBuf>,
}

/// Reads the shards in `dirs` (any order) and merges them.
///
/// # Errors
/// Any shard [`read_shard`] refuses; shards of different sweeps (version,
/// seed, runs, shard count, scenarios, duration); the same shard twice;
/// missing shards; a scenario that no longer parses. Each names the
/// directories concerned.
pub fn merge_shards(dirs: &[PathBuf]) -> anyhow::Result<MergedSweep> {
    let Some(first_dir) = dirs.first() else {
        bail!("no shard directories given");
    };
    let shards = dirs
        .iter()
        .map(|d| read_shard(d))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let first = &shards[0];
    let a = &first.manifest;
    ensure!(
        a.firmware_sim_version == VERSION,
        "{} was written by firmware-sim {}, this is {VERSION}: merge with the version that \
         ran the shards",
        first_dir.display(),
        a.firmware_sim_version
    );
    for other in &shards[1..] {
        let b = &other.manifest;
        let differ = |what: &str, x: String, y: String| {
            anyhow::anyhow!(
                "{} is a shard of another sweep than {}: {what} {y}, not {x}",
                other.dir.display(),
                first.dir.display()
            )
        };
        if b.firmware_sim_version != a.firmware_sim_version {
            return Err(differ(
                "written by firmware-sim",
                a.firmware_sim_version.clone(),
                b.firmware_sim_version.clone(),
            ));
        }
        if b.seed != a.seed {
            return Err(differ("seed", a.seed.to_string(), b.seed.to_string()));
        }
        if b.runs != a.runs {
            return Err(differ("runs", a.runs.to_string(), b.runs.to_string()));
        }
        if b.shards != a.shards {
            return Err(differ(
                "shard count N",
                a.shards.to_string(),
                b.shards.to_string(),
            ));
        }
        if b.names() != a.names() {
            let names = |m: &ShardManifest| format!("`{}`", m.names().join("`, `"));
            return Err(differ("scenarios", names(a), names(b)));
        }
        if b.duration_s != a.duration_s {
            let duration = |d: Option<f64>| d.map_or("none".to_owned(), |d| format!("{d} s"));
            return Err(differ(
                "--duration-s",
                duration(a.duration_s),
                duration(b.duration_s),
            ));
        }
        for (x, y) in a.scenarios.iter().zip(&b.scenarios) {
            ensure!(
                x.toml == y.toml,
                "{} is a shard of another sweep than {}: scenario `{}` has the same name but \
                 other content (compare the `toml` of their {MANIFEST})",
                other.dir.display(),
                first.dir.display(),
                x.name
            );
        }
    }
    let mut by_index: BTreeMap<u64, &ReadShard> = BTreeMap::new();
    for s in &shards {
        if let Some(before) = by_index.insert(s.manifest.shard, s) {
            if same_dir(&before.dir, &s.dir) {
                bail!(
                    "{} is given twice (shard {}/{})",
                    s.dir.display(),
                    s.manifest.shard,
                    s.manifest.shards
                );
            }
            bail!(
                "{} and {} are both shard {}/{}: keep one",
                before.dir.display(),
                s.dir.display(),
                s.manifest.shard,
                s.manifest.shards
            );
        }
    }
    let missing: Vec<u64> = (0..a.shards)
        .filter(|k| !by_index.contains_key(k))
        .collect();
    if !missing.is_empty() {
        let runs: usize = missing
            .iter()
            .filter_map(|&k| Shard::new(k, a.shards).ok())
            .map(|s| s.indices(a.runs).count())
            .sum();
        bail!(
            "missing shard{} {} of the {} ({runs} of the {} runs); have {}",
            if missing.len() == 1 { "" } else { "s" },
            missing
                .iter()
                .map(|k| format!("{k}/{}", a.shards))
                .collect::<Vec<_>>()
                .join(", "),
            a.shards,
            a.runs,
            by_index
                .values()
                .map(|s| format!("{}/{} in {}", s.manifest.shard, a.shards, s.dir.display()))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let mut results = Vec::new();
    for (i, scenario) in a.scenarios.iter().enumerate() {
        // Shards in K order hold contiguous blocks in index order.
        let rows: Vec<SweepRun> = by_index
            .values()
            .flat_map(|s| s.rows[i].iter().copied())
            .collect();
        ensure!(
            rows.iter().map(|r| r.index).eq(0..a.runs),
            "the shards' runs of `{}` are not the indices 0..{} (a bug: each shard was checked)",
            scenario.name,
            a.runs
        );
        let parsed = Scenario::from_toml_str(&scenario.toml).with_context(|| {
            format!(
                "{}: scenario `{}`",
                first.dir.join(MANIFEST).display(),
                scenario.name
            )
        })?;
        ensure!(
            parsed.name == scenario.name,
            "{}: scenario `{}` is named `{}` in its TOML",
            first.dir.join(MANIFEST).display(),
            scenario.name,
            parsed.name
        );
        results.push(summarize(&parsed, a.seed, rows)?);
    }
    Ok(MergedSweep {
        results,
        shards: by_index.values().map(|s| s.dir.clone()).collect(),
    })
}

/// Whether `a` and `b` are the same directory.
fn same_dir(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_are_contiguous_blocks_that_cover_the_runs_once() {
        for runs in [0, 1, 2, 7, 10, 100, 1001] {
            for count in [1, 2, 3, 7, 16] {
                let blocks: Vec<Range<u64>> = (0..count)
                    .map(|k| Shard::new(k, count).unwrap().indices(runs))
                    .collect();
                let all: Vec<u64> = blocks.iter().flat_map(Clone::clone).collect();
                assert_eq!(all, (0..runs).collect::<Vec<_>>(), "{runs} runs / {count}");
                let (min, max) = blocks.iter().fold((u64::MAX, 0), |(lo, hi), b| {
                    let n = b.end - b.start;
                    (lo.min(n), hi.max(n))
                });
                assert!(max - min <= 1, "{runs} runs / {count}: {blocks:?}");
            }
        }
        assert_eq!(Shard::new(2, 3).unwrap().indices(10), 6..10);
        let huge = Shard::new(u64::MAX - 1, u64::MAX).unwrap();
        assert_eq!(huge.indices(u64::MAX), u64::MAX - 1..u64::MAX);
    }

    #[test]
    fn shard_k_of_n_parses_from_zero_and_refuses_the_rest() {
        assert_eq!("0/1".parse::<Shard>(), Shard::new(0, 1));
        let s: Shard = "2/3".parse().unwrap();
        assert_eq!((s.index(), s.count(), s.to_string()), (2, 3, "2/3".into()));
        let e = "3/3".parse::<Shard>().unwrap_err();
        assert!(e.contains("counts from 0") && e.contains("2/3"), "{e}");
        let e = "0/0".parse::<Shard>().unwrap_err();
        assert!(e.contains("at least 1"), "{e}");
        for bad in ["", "1", "1/", "/3", "-1/3", "a/3", "1/3/4", "1.5/3"] {
            let e = bad.parse::<Shard>().unwrap_err();
            assert!(e.contains("expected K/N"), "{bad}: {e}");
        }
    }

    #[test]
    fn index_lists_are_described_as_ranges_when_they_are_one() {
        assert_eq!(describe_indices(&[3, 4, 5]), "3..6");
        assert_eq!(describe_indices(&[]), "[]");
        assert_eq!(describe_indices(&[0, 2]), "[0, 2]");
    }
}
