//! `firmware-sim hil`: a scenario with its control tick in the firmware under QEMU.

use super::{load, progress_bar};
use std::path::PathBuf;

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use firmware_sim::hil::{HilOptions, LinkFaultSpec, MavlinkBridgeSpec, run_hil};
use firmware_sim::output::{format_summary, write_all};
use firmware_sim::scenario::Scenario;
use firmware_sim::udp::MavlinkAddress;
use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};

/// The arguments of `hil`.
#[derive(Debug, clap::Args)]
pub struct HilArgs {
    /// Scenario file or embedded name; default:
    /// `figure_eight_rfid_full_stack_fusion_ekf` (the firmware's default
    /// estimator; `figure_eight_rfid_full_stack` runs paper 001's).
    scenario: Option<String>,
    /// Output directory (default: out/<scenario name>-hil).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Firmware ELF (default: build the QEMU-board firmware with cargo).
    #[arg(long)]
    firmware: Option<PathBuf>,
    /// Inject seeded faults on the link during the ticks, both ways:
    /// 1 % of bytes corrupted, 0.5 % of frames each dropped, duplicated
    /// and delayed by a frame, and an outage past the firmware's link
    /// timeout before 0.1 % of ticks (the faulty-link soak). Prints what was
    /// injected against what each side counted.
    #[arg(long, value_name = "SEED")]
    link_faults: Option<u64>,
    /// Override the scenario's duration, s.
    #[arg(long)]
    duration_s: Option<f64>,
    /// Longest wait for any answer of the firmware, s.
    #[arg(long, default_value_t = 10.0)]
    timeout_s: f64,
    /// Do not render run.png.
    #[arg(long)]
    no_plot: bool,
    /// A telemetry record on the firmware's log every N ticks (0:
    /// none); `firmware-sim plot OUT/firmware.log` reads them back.
    /// Default: the scenario's `telemetry.every_ticks` (its robot
    /// file's, when it names one), else 1 (every tick).
    #[arg(long, value_name = "N")]
    telemetry_every: Option<u16>,
    /// Also copy the decoded firmware log (OUT/firmware.log) to FILE.
    #[arg(long, value_name = "FILE")]
    firmware_log: Option<PathBuf>,
    /// Bridge a ground station to the firmware's MAVLink endpoint:
    /// `udp:HOST:PORT` sends to one listening there (QGroundControl
    /// listens on 14550), `udpin:HOST:PORT` listens there and answers the
    /// last sender (as `firmware-sim sitl`). The run is paced to wall
    /// time (`--speedup`), lasts its duration (Ctrl-C ends it early,
    /// cleanly) and needs a route.
    #[arg(long, value_name = "ADDRESS")]
    mavlink: Option<String>,
    /// With `--mavlink`: allow an address outside loopback (127.0.0.0/8,
    /// ::1): the robot is then reachable from other machines.
    #[arg(long, requires = "mavlink")]
    allow_non_loopback: bool,
    /// With `--mavlink`: times real time (a tick may take at most 25 ms of
    /// wall time); a machine that cannot keep up runs flat out.
    #[arg(long, requires = "mavlink", default_value_t = 1.0)]
    speedup: f64,
    /// The robot's `[mavlink]` settings, overridden (as `firmware-sim
    /// sitl`'s): they reach the firmware with the route.
    #[command(flatten)]
    endpoint: super::sitl::MavlinkOverrides,
}

/// Prints the bridge's address line.
fn announce(line: &str) {
    eprintln!("hil: {line}");
}

impl HilArgs {
    /// Runs the subcommand.
    pub fn run(self) -> anyhow::Result<()> {
        let Self {
            scenario,
            out,
            firmware,
            duration_s,
            timeout_s,
            link_faults,
            no_plot,
            telemetry_every,
            firmware_log,
            mavlink,
            allow_non_loopback,
            speedup,
            endpoint,
        } = self;
        let mut scenario = match scenario {
            None => Scenario::embedded("figure_eight_rfid_full_stack_fusion_ekf")?,
            Some(arg) => load(&arg)?,
        };
        // Only for a route (a trajectory run has no endpoint: the table
        // would be a warning there).
        if matches!(
            scenario.reference,
            firmware_sim::scenario::ReferenceSpec::Route(_)
        ) {
            endpoint.apply(&mut scenario);
        }
        if let Some(d) = duration_s {
            scenario.duration_s = d;
            if scenario.transient_s >= d {
                scenario.transient_s = 0.0;
            }
        }
        anyhow::ensure!(
            timeout_s.is_finite() && timeout_s > 0.0,
            "--timeout-s must be positive"
        );
        let mavlink = match mavlink {
            Some(address) => {
                // SIGHUP too: QEMU, in a process group of its own, would
                // outlive a closed terminal's hang-up otherwise.
                let stop = Arc::new(AtomicBool::new(false));
                for signal in [SIGINT, SIGTERM, SIGHUP] {
                    signal_hook::flag::register(signal, Arc::clone(&stop))?;
                }
                Some(MavlinkBridgeSpec {
                    address: MavlinkAddress::parse(&address, allow_non_loopback)?,
                    speedup,
                    stop: Some(stop),
                    stops_on_signals: true,
                    announce: Some(announce),
                })
            }
            None => None,
        };
        let out =
            out.unwrap_or_else(|| PathBuf::from("out").join(format!("{}-hil", scenario.name)));
        std::fs::create_dir_all(&out)?;
        let options = HilOptions {
            firmware,
            log: Some(out.join("firmware.defmt")),
            answer_timeout: std::time::Duration::from_secs_f64(timeout_s),
            faults: link_faults.map(LinkFaultSpec::soak),
            telemetry_every_ticks: match telemetry_every {
                Some(n) => n,
                None => firmware_sim::hil::default_telemetry_every_ticks(&scenario)?,
            },
            mavlink,
        };
        let bar = progress_bar(&scenario, 0.0)?;
        let run = run_hil(&scenario, &options, |done, _| bar.set_position(done));
        bar.finish_and_clear();
        let run = run?;
        let files = write_all(&out, &run.result, !no_plot)?;
        if let Some(copy) = &firmware_log {
            std::fs::copy(out.join("firmware.log"), copy).map_err(|e| {
                anyhow::anyhow!("copying the firmware log to {}: {e}", copy.display())
            })?;
        }
        out!("{}", format_summary(&run.result.summary));
        outln!(
            "firmware      {} (log: {})",
            run.firmware.display(),
            firmware_log
                .as_deref()
                .unwrap_or(&out.join("firmware.log"))
                .display()
        );
        outln!(
            "wrote         {}, {}{}",
            files.csv.display(),
            files.summary.display(),
            files
                .plot
                .map(|p| format!(", {}", p.display()))
                .unwrap_or_default()
        );
        Ok(())
    }
}
