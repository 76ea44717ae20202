//! The committed on-target budgets (`firmware/budgets.toml`) and their
//! check: `bench-target` and `size` fail when a figure exceeds its budget
//! by more than the file's tolerance, and report budgets that have gone
//! stale (the figure well below them) and issue 15's targets.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use crate::target::workspace_root;

/// The budget file, relative to the workspace root.
pub const FILE: &str = "firmware/budgets.toml";

/// The parsed budget file.
#[derive(Debug, Clone, PartialEq)]
pub struct Budgets {
    /// Relative slack above a budget before it fails.
    pub tolerance: f64,
    /// Relative margin below a budget reported as stale.
    pub stale_below: f64,
    /// Absolute slack above a budget, in the figure's unit, for small
    /// figures.
    pub min_slack: f64,
    /// Mean instructions per call, by bench stage.
    pub instructions: BTreeMap<String, f64>,
    /// Peak stack, bytes, by bench stage.
    pub stack_bytes: BTreeMap<String, f64>,
    /// Flash as shipped, bytes, by board.
    pub flash_bytes: BTreeMap<String, f64>,
    /// Hard flash limit, bytes, by board.
    pub flash_limit_bytes: BTreeMap<String, f64>,
    /// Issue targets, instructions, by `+`-joined stage names.
    pub targets: BTreeMap<String, f64>,
}

/// One figure against its budget.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// What was measured (`instructions robot_tick`, `flash board-qemu`).
    pub what: String,
    /// The figure.
    pub figure: f64,
    /// Its budget.
    pub budget: f64,
    /// Over budget beyond the tolerance.
    pub over: bool,
    /// Below budget beyond the stale margin.
    pub stale: bool,
}

fn table(root: &toml::Table, key: &str) -> Result<BTreeMap<String, f64>, String> {
    let Some(value) = root.get(key) else {
        return Ok(BTreeMap::new());
    };
    let t = value
        .as_table()
        .ok_or_else(|| format!("{FILE}: [{key}] must be a table"))?;
    t.iter()
        .map(|(name, v)| {
            let n = v
                .as_integer()
                .map(|i| i as f64)
                .or_else(|| v.as_float())
                .filter(|n| n.is_finite() && *n > 0.0)
                .ok_or_else(|| format!("{FILE}: {key}.{name} must be a positive number"))?;
            Ok((name.clone(), n))
        })
        .collect()
}

fn fraction(root: &toml::Table, key: &str) -> Result<f64, String> {
    root.get(key)
        .and_then(toml::Value::as_float)
        .filter(|f| (0.0..1.0).contains(f))
        .ok_or_else(|| format!("{FILE}: `{key}` must be a number in [0, 1)"))
}

impl Budgets {
    /// Parses the budget file's text.
    ///
    /// # Errors
    /// A message naming the key that is missing or malformed.
    pub fn parse(text: &str) -> Result<Self, String> {
        let root: toml::Table = text.parse().map_err(|e| format!("{FILE}: {e}"))?;
        for key in root.keys() {
            if !matches!(
                key.as_str(),
                "tolerance"
                    | "stale_below"
                    | "min_slack"
                    | "instructions"
                    | "stack_bytes"
                    | "flash_bytes"
                    | "flash_limit_bytes"
                    | "targets"
                    // Checked by the HIL tests (host-tests/tests/hil.rs),
                    // which measure them.
                    | "hil_peak_stack_bytes"
                    | "hil_peak_stack_limit_bytes"
                    | "robot_flash_bytes"
                    | "robot_flash_limit_bytes"
            ) {
                return Err(format!("{FILE}: unknown key `{key}`"));
            }
        }
        Ok(Self {
            tolerance: fraction(&root, "tolerance")?,
            stale_below: fraction(&root, "stale_below")?,
            min_slack: root
                .get("min_slack")
                .and_then(|v| v.as_integer().map(|i| i as f64).or_else(|| v.as_float()))
                .filter(|s| s.is_finite() && *s >= 0.0)
                .ok_or_else(|| format!("{FILE}: `min_slack` must be a number ≥ 0"))?,
            instructions: table(&root, "instructions")?,
            stack_bytes: table(&root, "stack_bytes")?,
            flash_bytes: table(&root, "flash_bytes")?,
            flash_limit_bytes: table(&root, "flash_limit_bytes")?,
            targets: table(&root, "targets")?,
        })
    }

    /// Reads [`FILE`].
    ///
    /// # Errors
    /// The file cannot be read or parsed.
    pub fn load() -> Result<Self, String> {
        let path = workspace_root().join(FILE);
        let text =
            std::fs::read_to_string(&path).map_err(|e| format!("read {}: {e}", path.display()))?;
        Self::parse(&text)
    }

    fn verdict(&self, what: String, figure: f64, budget: f64) -> Verdict {
        Verdict {
            what,
            figure,
            budget,
            over: figure > budget + (budget * self.tolerance).max(self.min_slack),
            stale: figure < budget * (1.0 - self.stale_below),
        }
    }

    /// Every budget of `kind` (`budgets`) against `figures`; a budget with
    /// no figure is an error (a renamed or removed stage must leave the
    /// file too).
    ///
    /// # Errors
    /// The budgets that have no figure.
    pub fn check(
        &self,
        kind: &str,
        budgets: &BTreeMap<String, f64>,
        figure: impl Fn(&str) -> Option<f64>,
    ) -> Result<Vec<Verdict>, String> {
        let mut missing = Vec::new();
        let verdicts = budgets
            .iter()
            .filter_map(|(name, &budget)| match figure(name) {
                Some(f) => Some(self.verdict(format!("{kind} {name}"), f, budget)),
                None => {
                    missing.push(name.clone());
                    None
                }
            })
            .collect();
        if missing.is_empty() {
            Ok(verdicts)
        } else {
            Err(format!(
                "{FILE}: [{kind}] names what this run did not measure: {}",
                missing.join(", ")
            ))
        }
    }

    /// The targets against the stage means `figure` gives (a target whose
    /// stage is missing reads "not measured").
    pub fn targets_report(&self, figure: impl Fn(&str) -> Option<f64>) -> String {
        let mut md = String::from("| target | figure | target | |\n| --- | ---: | ---: | --- |\n");
        for (name, &target) in &self.targets {
            let sum: Option<f64> = name.split('+').map(|stage| figure(stage.trim())).sum();
            let _ = match sum {
                Some(f) => writeln!(
                    md,
                    "| {name} | {f:.0} | {target:.0} | {} |",
                    if f <= target { "met" } else { "not met" }
                ),
                None => writeln!(md, "| {name} | not measured | {target:.0} | |"),
            };
        }
        md
    }
}

/// The verdicts as a table, and Err listing every figure over budget.
///
/// # Errors
/// One or more figures over budget.
pub fn report(verdicts: &[Verdict], tolerance: f64) -> (String, crate::Result) {
    let mut md = String::from("| budget | figure | budget | |\n| --- | ---: | ---: | --- |\n");
    for v in verdicts {
        let state = if v.over {
            "**over**"
        } else if v.stale {
            "stale: lower it"
        } else {
            "ok"
        };
        let _ = writeln!(
            md,
            "| {} | {:.0} | {:.0} | {state} |",
            v.what, v.figure, v.budget
        );
    }
    let over: Vec<String> = verdicts
        .iter()
        .filter(|v| v.over)
        .map(|v| format!("{} {:.0} > {:.0}", v.what, v.figure, v.budget))
        .collect();
    let result = if over.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "over budget by more than {:.0} % ({FILE}): {}. Find the regression, or raise \
             the budget in {FILE} in a commit that says why.",
            tolerance * 100.0,
            over.join("; ")
        ))
    };
    (md, result)
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "tolerance = 0.02\nstale_below = 0.1\nmin_slack = 1\n[instructions]\na = 100\nb = 200\n\
                        [targets]\n\"a+b\" = 250\n";

    #[test]
    fn the_committed_file_parses() {
        let b = Budgets::load().unwrap();
        assert!(b.instructions.contains_key("robot_tick"));
        assert!(b.flash_limit_bytes.contains_key("board-qemu"));
    }

    #[test]
    fn over_stale_and_missing() {
        let b = Budgets::parse(TEXT).unwrap();
        let figures = |name: &str| match name {
            "a" => Some(102.0),
            "b" => Some(205.0),
            _ => None,
        };
        let v = b.check("instructions", &b.instructions, figures).unwrap();
        assert_eq!((v[0].over, v[0].stale), (false, false));
        assert!(v[1].over);
        let (_, result) = report(&v, b.tolerance);
        assert!(result.unwrap_err().contains("instructions b 205 > 200"));
        let low = b
            .check("instructions", &b.instructions, |_| Some(50.0))
            .unwrap();
        assert!(low.iter().all(|v| v.stale && !v.over));
        assert!(
            b.check("instructions", &b.instructions, |n| (n == "a")
                .then_some(1.0))
                .unwrap_err()
                .contains(": b")
        );
        assert!(
            b.targets_report(figures)
                .contains("| a+b | 307 | 250 | not met |")
        );
    }

    #[test]
    fn malformed_files_name_the_key() {
        assert!(
            Budgets::parse("tolerance = 0.02\nstale_below = 0.1\nmin_slack = 1\nbudget = 1\n")
                .unwrap_err()
                .contains("`budget`")
        );
        assert!(
            Budgets::parse("tolerance = 2.0\nstale_below = 0.1\nmin_slack = 1\n")
                .unwrap_err()
                .contains("`tolerance`")
        );
        assert!(
            Budgets::parse(
                "tolerance = 0.02\nstale_below = 0.1\nmin_slack = 1\n[instructions]\na = -1\n"
            )
            .unwrap_err()
            .contains("instructions.a")
        );
    }
}
