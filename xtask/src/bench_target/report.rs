//! What one run of `wmr-bench` reported, parsed from its semihosting
//! output.

use super::benches::{PF_TICK, ROUTE_TICK};

/// One stage's instruction counts.
#[derive(Debug, Clone, PartialEq)]
pub struct Stat {
    /// Bench name.
    pub name: String,
    /// Mean instructions per call.
    pub mean: f64,
    /// Median, instructions (±1 SysTick count).
    pub median: i64,
    /// Smallest sample, instructions.
    pub min: i64,
    /// Largest sample, instructions.
    pub max: i64,
}

/// One of paper 004's filters, as the bench left it.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterRun {
    /// Bench name (`ekf3`, …).
    pub name: String,
    /// `size_of` the filter on the target, bytes.
    pub state_bytes: u64,
    /// RMS position error over the sampled steps, m.
    pub position_rms_error_m: f64,
    /// Particle-filter resamplings over the whole run.
    pub resamplings: u64,
    /// Steps (predict + update) of the whole run.
    pub steps: u64,
}

/// What one run of `wmr-bench` reported.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// Math backend the binary was built with.
    pub backend: String,
    /// The QEMU machine it ran on (`netduinoplus2` when the output does not
    /// say).
    pub machine: String,
    /// Samples per stage.
    pub samples: u32,
    /// SysTick counts per instruction found by the calibration.
    pub counts_per_instruction: f64,
    /// The measurement's own instructions (subtracted).
    pub overhead_instructions: f64,
    /// Every `bench` line.
    pub stats: Vec<Stat>,
    /// Peak stack of one tick below its caller's stack pointer, bytes.
    pub tick_stack_bytes: u64,
    /// Peak stack of one call of each other measured stage (paper 004's
    /// filter steps), bytes.
    pub stacks: Vec<(String, u64)>,
    /// Every `filter` line.
    pub filters: Vec<FilterRun>,
    /// Flash and static RAM of the `wmr-bench` ELF, bytes (set by
    /// [`run_backend`](super::run_backend), not by the output).
    pub elf_flash_ram: Option<(u64, u64)>,
}

impl Report {
    /// The stage called `name`.
    pub fn stat(&self, name: &str) -> Option<&Stat> {
        self.stats.iter().find(|s| s.name == name)
    }

    /// The stack of the stage called `name` (not the tick's).
    pub fn stack(&self, name: &str) -> Option<u64> {
        self.stacks.iter().find(|s| s.0 == name).map(|s| s.1)
    }

    /// Takes the particle filter's whole-tick stages and stack
    /// ([`PF_TICK`]) from `pf`, the same backend's run built with
    /// [`PF_FEATURES`](super::benches::PF_FEATURES) (whose other figures
    /// are not this build's).
    ///
    /// # Errors
    /// `pf` lacks one of them, or this run already has one.
    pub fn take_pf_tick(&mut self, pf: &Report) -> Result<(), String> {
        let [fix, dead_reckoned, stack] = PF_TICK;
        self.take_stats(pf, &[fix, dead_reckoned], "particle-filter")?;
        let bytes = pf.stack(stack).ok_or_else(|| {
            format!(
                "the {} particle-filter build reported no stack {stack}",
                pf.backend
            )
        })?;
        self.stacks.push((stack.to_owned(), bytes));
        Ok(())
    }

    /// Takes the whole tick on a route ([`ROUTE_TICK`]) from `route`, the
    /// same backend's run built with
    /// [`ROUTE_FEATURES`](super::benches::ROUTE_FEATURES) (whose other
    /// figures are not this build's).
    ///
    /// # Errors
    /// `route` lacks it, or this run already has it.
    pub fn take_route_tick(&mut self, route: &Report) -> Result<(), String> {
        self.take_stats(route, &[ROUTE_TICK], "route-tick")
    }

    /// Copies the stages `names` from `other`, a build of its own (`what`).
    fn take_stats(&mut self, other: &Report, names: &[&str], what: &str) -> Result<(), String> {
        for &name in names {
            if self.stat(name).is_some() {
                return Err(format!("the {} build measured {name}", self.backend));
            }
            let stat = other
                .stat(name)
                .ok_or_else(|| format!("the {} {what} build measured no {name}", other.backend))?;
            self.stats.push(stat.clone());
        }
        Ok(())
    }

    /// The filter called `name`.
    pub fn filter(&self, name: &str) -> Option<&FilterRun> {
        self.filters.iter().find(|f| f.name == name)
    }
}

/// `key=value` fields of a line.
fn field<T: std::str::FromStr>(line: &str, key: &str) -> Result<T, String> {
    line.split_whitespace()
        .find_map(|w| w.strip_prefix(key)?.strip_prefix('='))
        .ok_or_else(|| format!("no `{key}=` in `{line}`"))?
        .parse()
        .map_err(|_| format!("bad `{key}=` in `{line}`"))
}

/// Parses the bench's semihosting output.
pub fn parse(output: &str) -> Result<Report, String> {
    let mut report = Report {
        backend: String::new(),
        machine: "netduinoplus2".into(),
        samples: 0,
        counts_per_instruction: 0.0,
        overhead_instructions: 0.0,
        stats: Vec::new(),
        tick_stack_bytes: 0,
        stacks: Vec::new(),
        filters: Vec::new(),
        elf_flash_ram: None,
    };
    let (mut header, mut calibrated, mut stack, mut done) = (false, false, false, false);
    for line in output.lines().map(str::trim) {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("wmr-bench") => {
                report.backend = field(line, "backend")?;
                report.samples = field(line, "samples")?;
                if let Ok(machine) = field::<String>(line, "machine") {
                    report.machine = machine;
                }
                header = true;
            }
            Some("calibration") => {
                report.counts_per_instruction = field(line, "counts_per_instruction")?;
                report.overhead_instructions = field(line, "overhead_instructions")?;
                calibrated = true;
            }
            Some("bench") => {
                let name = words.next().ok_or_else(|| format!("no name in `{line}`"))?;
                report.stats.push(Stat {
                    name: name.to_string(),
                    mean: field(line, "mean")?,
                    median: field(line, "median")?,
                    min: field(line, "min")?,
                    max: field(line, "max")?,
                });
            }
            Some("stack") => {
                let name = words.next().ok_or_else(|| format!("no name in `{line}`"))?;
                let bytes = field(line, "bytes")?;
                if name == "robot_tick" {
                    report.tick_stack_bytes = bytes;
                    stack = true;
                } else {
                    report.stacks.push((name.to_string(), bytes));
                }
            }
            Some("filter") => {
                let name = words.next().ok_or_else(|| format!("no name in `{line}`"))?;
                report.filters.push(FilterRun {
                    name: name.to_string(),
                    state_bytes: field(line, "state_bytes")?,
                    position_rms_error_m: field(line, "position_rms_error_m")?,
                    resamplings: field(line, "resamplings")?,
                    steps: field(line, "steps")?,
                });
            }
            Some("error") => return Err(format!("the bench failed: {line}")),
            Some("done") => done = true,
            _ => {}
        }
    }
    match (header, calibrated, stack, done) {
        (true, true, true, true) => Ok(report),
        _ => Err(format!("incomplete bench output:\n{output}")),
    }
}
