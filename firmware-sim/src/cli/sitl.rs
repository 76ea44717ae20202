//! `firmware-sim sitl`: the simulated robot behind MAVLink on UDP.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use firmware_sim::output::write_csv;
use firmware_sim::sitl::{self, MavlinkAddress, SitlOptions};
use wmr_mavlink::EndpointSpec;

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
    /// The floor's geodetic origin `LAT,LON` (degrees, WGS-84): global
    /// frame missions and GLOBAL_POSITION_INT.
    #[arg(long, value_parser = parse_origin, allow_hyphen_values = true)]
    origin: Option<(i32, i32)>,
    /// MAVLink system id.
    #[arg(long, default_value_t = 1)]
    system_id: u8,
    /// Position and attitude telemetry period, simulated ms (0: off).
    #[arg(long, default_value_t = 200)]
    telemetry_period_ms: u32,
    /// No ground-station heartbeat for this long (simulated ms): link lost.
    #[arg(long, default_value_t = 3000)]
    link_timeout_ms: u32,
    /// Write run.csv (every tick) and sitl.json (the report) here at
    /// the end of the run.
    #[arg(long)]
    out: Option<PathBuf>,
}

/// `LAT,LON` in degrees to 1e-7 degrees.
fn parse_origin(text: &str) -> Result<(i32, i32), String> {
    let (lat, lon) = text
        .split_once(',')
        .ok_or_else(|| format!("{text}: expected LAT,LON"))?;
    let e7 = |s: &str, name: &str, max: f64| -> Result<i32, String> {
        let v: f64 = s.trim().parse().map_err(|e| format!("{name} {s}: {e}"))?;
        if !(v.is_finite() && v.abs() <= max) {
            return Err(format!("{name} {s}: must be within ±{max}°"));
        }
        Ok((v * 1e7).round() as i32)
    };
    Ok((e7(lat, "latitude", 90.0)?, e7(lon, "longitude", 180.0)?))
}

impl SitlArgs {
    /// Runs the subcommand.
    pub fn run(self) -> anyhow::Result<()> {
        let scenario = load(&self.scenario)?;
        let setup = scenario.validate()?;
        let address = MavlinkAddress::parse(&self.mavlink, self.allow_non_loopback)?;
        let options = SitlOptions {
            address,
            speedup: self.speedup,
            duration_s: self.duration_s,
            endpoint: EndpointSpec {
                system_id: self.system_id,
                telemetry_period_ms: self.telemetry_period_ms,
                link_timeout_ms: self.link_timeout_ms,
                origin_e7: self.origin,
                ..EndpointSpec::default()
            },
            keep_records: self.out.is_some(),
        };
        let stop = AtomicBool::new(false);
        let report = sitl::run(&setup, &options, &stop, |link| {
            eprintln!(
                "sitl: {} on MAVLink, {}, {}x real time",
                scenario.name,
                link.describe(),
                options.speedup
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
