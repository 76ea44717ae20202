//! `firmware-sim schema`: every key of a scenario file and a robot file
//! (`run`, `sweep`, `hil`), or of a slip scenario file (`slip`).

/// The arguments of `schema`.
#[derive(Debug, clap::Args)]
pub struct SchemaArgs {
    /// The JSON Schema (draft 2020-12) instead of the table (of the
    /// scenario file; with `--robot` or `--slip`, of that file).
    #[arg(long)]
    json: bool,
    /// The robot file's keys only (`robot = "FILE"` in a scenario, its
    /// `[robot]` table, `cargo xtask firmware --robot FILE`); without it
    /// the table lists the scenario file's keys, then the robot file's.
    #[arg(long)]
    robot: bool,
    /// The slip scenario file's keys (`firmware-sim slip FILE`, paper
    /// 004's tracked robot): its own format, not a scenario file's.
    #[arg(long, conflicts_with = "robot")]
    slip: bool,
}

impl SchemaArgs {
    /// Runs the subcommand.
    pub fn run(self) -> anyhow::Result<()> {
        let Self { json, robot, slip } = self;
        use firmware_sim::scenario::keys;
        if json {
            let schema = if slip {
                firmware_sim::slip::slip_schema()
            } else if robot {
                keys::robot_schema()
            } else {
                keys::scenario_schema()
            };
            outln!("{}", serde_json::to_string_pretty(&schema)?);
        } else if slip {
            out!("{}", keys::markdown(&firmware_sim::slip::slip_keys()));
        } else if robot {
            out!("{}", keys::markdown(&keys::robot_keys()));
        } else {
            out!("{}", keys::markdown(&keys::scenario_keys()));
            outln!(
                "\nRobot file (`robot = \"FILE\"` in a scenario, or its `[robot]` table; \
                     `cargo xtask firmware --robot FILE`):\n"
            );
            out!("{}", keys::markdown(&keys::robot_keys()));
        }
        Ok(())
    }
}
