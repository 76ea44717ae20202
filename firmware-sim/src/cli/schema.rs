//! `firmware-sim schema`: every key of a scenario and a robot file.

/// The arguments of `schema`.
#[derive(Debug, clap::Args)]
pub struct SchemaArgs {
    /// The JSON Schema (draft 2020-12) instead of the table.
    #[arg(long)]
    json: bool,
    /// With `--json`: the robot file's schema.
    #[arg(long)]
    robot: bool,
}

impl SchemaArgs {
    /// Runs the subcommand.
    pub fn run(self) -> anyhow::Result<()> {
        let Self { json, robot } = self;
        use firmware_sim::scenario::keys;
        if json {
            let schema = if robot {
                keys::robot_schema()
            } else {
                keys::scenario_schema()
            };
            outln!("{}", serde_json::to_string_pretty(&schema)?);
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
