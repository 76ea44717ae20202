//! `firmware-sim robot-image`: a robot file validated into its flash image.

use std::path::PathBuf;

/// The arguments of `robot-image`.
#[derive(Debug, clap::Args)]
pub struct RobotImageArgs {
    /// The robot file (TOML).
    robot: PathBuf,
    /// Where to write the image.
    #[arg(long)]
    out: PathBuf,
}

impl RobotImageArgs {
    /// Runs the subcommand.
    pub fn run(self) -> anyhow::Result<()> {
        let Self { robot, out } = self;
        use firmware_sim::scenario::robot::{FlashFloor, Robot};
        let robot_file = Robot::from_file(&robot)?;
        for warning in robot_file.warnings() {
            eprintln!("warning: {warning}");
        }
        let image = robot_file.flash_image()?;
        std::fs::write(&out, &image.bytes)
            .map_err(|e| anyhow::anyhow!("writing {}: {e}", out.display()))?;
        let floor = match &image.floor {
            FlashFloor::Grid(g) => format!(
                "tag grid {} × {} at {} m from ({}, {}) m",
                g.columns, g.rows, g.spacing_m, g.origin_m[0], g.origin_m[1]
            ),
            FlashFloor::Map(tags) => format!("tag map of {} tags", tags.len()),
        };
        let route = image.route.as_ref().map_or_else(String::new, |(_, w)| {
            format!(", a route of {} waypoints", w.len())
        });
        outln!(
            "{}: {} B image ({floor}{route}, telemetry every {} ticks) -> {}",
            robot.display(),
            image.bytes.len(),
            image.telemetry_every_ticks,
            out.display()
        );
        // Read by `cargo xtask firmware --robot`.
        outln!(
            "firmware features: {}",
            firmware_sim::hil::firmware_features(&image.pilot).join(",")
        );
        Ok(())
    }
}
