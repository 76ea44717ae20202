//! `firmware-sim sitl`: the simulated robot behind MAVLink on UDP.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use firmware_sim::output::write_csv;
use firmware_sim::scenario::Scenario;
use firmware_sim::scenario::mavlink::{MavlinkSpec, OriginSpec, PowerOnSpec};
use firmware_sim::sitl::{self, MavlinkAddress, SitlOptions};

use super::load;

/// The arguments of `sitl`.
#[derive(Debug, clap::Args)]
pub struct SitlArgs {
    /// A route scenario file (TOML), a robot file with a route, or the name
    /// of an embedded route scenario (`route`, `warehouse_loop`).
    scenario: String,
    /// `udp:HOST:PORT`: send to a ground station listening there
    /// (QGroundControl listens on 14550), answer from an ephemeral port;
    /// `udpin:HOST:PORT`: listen there, answer the last sender.
    #[arg(long, default_value = "udp:127.0.0.1:14550")]
    mavlink: String,
    /// Allow an address outside loopback (127.0.0.0/8, ::1): the robot
    /// is then reachable from other machines.
    #[arg(long)]
    allow_non_loopback: bool,
    /// Times real time; a machine that cannot keep up runs flat out.
    #[arg(long, default_value_t = 1.0)]
    speedup: f64,
    /// Simulated seconds to run (default: until interrupted).
    #[arg(long)]
    duration_s: Option<f64>,
    /// The robot's `[mavlink]` settings, overridden.
    #[command(flatten)]
    endpoint: MavlinkOverrides,
    /// Write run.csv (every tick) and sitl.json (the report) here at
    /// the end of the run.
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Command-line overrides of a scenario's or robot file's `[mavlink]`
/// table (`firmware-sim sitl`, `firmware-sim hil`): checked with the
/// table, by the same code, naming the table's key.
#[derive(Debug, clap::Args)]
pub struct MavlinkOverrides {
    /// The floor's geodetic origin `LAT,LON` (degrees, WGS-84): global
    /// frame missions and GLOBAL_POSITION_INT (`mavlink.origin`).
    #[arg(long, value_parser = parse_origin, allow_hyphen_values = true)]
    origin: Option<(f64, f64)>,
    /// MAVLink system id (`mavlink.system_id`, default 1).
    #[arg(long)]
    system_id: Option<u64>,
    /// Position and attitude telemetry period, ms of the robot's time, 0:
    /// off (`mavlink.telemetry_period_ms`, default 200).
    #[arg(long)]
    telemetry_period_ms: Option<u64>,
    /// No ground-station heartbeat for this long (ms of the robot's
    /// time): link lost (`mavlink.link_timeout_ms`, default 3000).
    #[arg(long)]
    link_timeout_ms: Option<u64>,
    /// At power-on: `run` the route armed, or `wait` disarmed and idle
    /// with the route as the mission (`mavlink.power_on`, default `run`).
    #[arg(long, value_parser = ["run", "wait"])]
    power_on: Option<String>,
}

impl MavlinkOverrides {
    /// Writes the overrides into `scenario`'s `[mavlink]` table (its
    /// robot file's, once resolved), which validation checks.
    pub fn apply(&self, scenario: &mut Scenario) {
        let table = scenario.mavlink.get_or_insert_with(MavlinkSpec::default);
        if let Some((latitude_deg, longitude_deg)) = self.origin {
            table.origin = Some(OriginSpec {
                latitude_deg,
                longitude_deg,
            });
        }
        if let Some(v) = self.system_id {
            table.system_id = v;
        }
        if let Some(v) = self.telemetry_period_ms {
            table.telemetry_period_ms = v;
        }
        if let Some(v) = self.link_timeout_ms {
            table.link_timeout_ms = v;
        }
        match self.power_on.as_deref() {
            Some("wait") => table.power_on = PowerOnSpec::Wait,
            Some("run") => table.power_on = PowerOnSpec::Run,
            _ => {}
        }
    }
}

/// `LAT,LON` in degrees (their range is the `[mavlink.origin]` table's
/// check).
fn parse_origin(text: &str) -> Result<(f64, f64), String> {
    let (lat, lon) = text
        .split_once(',')
        .ok_or_else(|| format!("{text}: expected LAT,LON"))?;
    let deg = |s: &str, name: &str| -> Result<f64, String> {
        s.trim().parse().map_err(|e| format!("{name} {s}: {e}"))
    };
    Ok((deg(lat, "latitude")?, deg(lon, "longitude")?))
}

impl SitlArgs {
    /// Runs the subcommand.
    pub fn run(self) -> anyhow::Result<()> {
        let mut scenario = load(&self.scenario)?;
        self.endpoint.apply(&mut scenario);
        let setup = scenario.validate()?;
        let address = MavlinkAddress::parse(&self.mavlink, self.allow_non_loopback)?;
        let options = SitlOptions {
            address,
            speedup: self.speedup,
            duration_s: self.duration_s,
            keep_records: self.out.is_some(),
        };
        let stop = AtomicBool::new(false);
        let report = sitl::run(&setup, &options, &stop, |link| {
            eprintln!(
                "sitl: {} on MAVLink, {}, {}x real time, {}",
                scenario.name,
                link.describe(),
                options.speedup,
                match setup.route.as_ref().map(|r| r.mavlink.power_on) {
                    Some(wmr_link::PowerOn::Wait) => "waiting disarmed (power_on = \"wait\")",
                    _ => "running its route (power_on = \"run\")",
                }
            );
        })?;
        for line in &report.log {
            eprintln!("sitl: {line}");
        }
        eprintln!(
            "sitl: {:.1} s simulated in {:.2} s ({:.1}x real time)",
            report.sim_s, report.wall_s, report.speedup_achieved
        );
        if let Some(dir) = &self.out {
            std::fs::create_dir_all(dir)?;
            write_csv(&dir.join("run.csv"), &report.records)?;
            std::fs::write(
                dir.join("sitl.json"),
                serde_json::to_string_pretty(&report)? + "\n",
            )?;
            eprintln!("sitl: wrote {}", dir.display());
        }
        Ok(())
    }
}
