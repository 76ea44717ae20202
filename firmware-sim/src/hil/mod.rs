//! Hardware-in-the-loop: the real firmware binary under QEMU, in lock-step
//! with the simulator.
//!
//! ```text
//! firmware-sim                         qemu-system-arm -M netduinoplus2
//!  plant, encoders, RFID reader ─Tick─► file ─► wmr-firmware (board-qemu)
//!  virtual PWM + DIR pins ◄──Ticked─── pipe ◄─ core Robot on link proxies
//! ```
//!
//! The link's frames go through two files in QEMU's working directory (a
//! temporary one), which the firmware reads and writes by semihosting:
//! the host appends to a regular file and reads a named pipe (see
//! `qemu`: one system call a frame each way, where QEMU's USART model woke
//! a thread per byte). The firmware's defmt log (semihosting, QEMU's stdout) is saved raw next to
//! the run (`firmware.defmt`) and decoded with the ELF's format table into
//! `firmware.log`. The run
//! ends with `Finish`: the firmware reports its stack high-water mark and
//! exits through semihosting; QEMU is killed if it does not exit.
//!
//! `firmware` builds the ELF and decodes its log, `qemu` runs it and
//! speaks the link ([`QemuTarget`], a
//! [`TargetLink`](crate::simulation::TargetLink)), `mavlink` bridges a
//! ground station on UDP to the link's MAVLink channel before each tick
//! (`--mavlink`, with `crate::udp`, the SITL's UDP code); this file runs a scenario
//! through them ([`run_hil`]).

use std::path::PathBuf;

use anyhow::{Context, ensure};
use wmr_core::pilot::spec::PilotSpec;

use crate::report::{HilReport, RunResult};
use crate::scenario::{ReferenceSpec, Scenario};
use crate::simulation::{hil_configuration, hil_map_chunks, hil_route_messages, run_with_target};

mod faults;
mod firmware;
mod mavlink;
mod qemu;

pub use crate::report::mavlink_bridge::MavlinkBridgeReport;
pub use faults::{ExpectedCounters, InjectedFaults, LinkFaultReport, LinkFaultSpec, OUTAGE_MS};
pub use firmware::{
    FIRMWARE_TARGET, HIL_FIRMWARE_ENV, build_firmware, build_firmware_with, decode_defmt_log,
    hil_test_firmware, workspace_root,
};
pub use mavlink::{BACKLOG_BYTES, MAX_WALL_PER_TICK_S, MavlinkBridgeSpec};
pub use qemu::{DEFAULT_TELEMETRY_EVERY_TICKS, HilOptions, QEMU, QemuTarget};

/// A run through the firmware.
#[derive(Debug, Clone)]
pub struct HilRun {
    /// The same records and summary as a local run.
    pub result: RunResult,
    /// The link and target figures.
    pub report: HilReport,
    /// The firmware that ran.
    pub firmware: PathBuf,
}

/// The firmware's cargo features `pilot` needs beyond what both boards
/// carry (the fusion EKF): the wheel-speed observer, the fusion
/// estimator's UKF or particle filter.
#[must_use]
pub fn firmware_features(pilot: &PilotSpec) -> Vec<&'static str> {
    pilot.required_builds().map(|build| build.feature).collect()
}

/// The telemetry decimation of a HIL run of `scenario` when none is asked
/// for (`firmware-sim hil` without `--telemetry-every`): the scenario's
/// `telemetry.every_ticks` (its robot file's, when it names one), else
/// [`DEFAULT_TELEMETRY_EVERY_TICKS`].
///
/// # Errors
/// `telemetry.every_ticks` out of range (not 1 to 65535).
pub fn default_telemetry_every_ticks(scenario: &Scenario) -> anyhow::Result<u16> {
    Ok(match &scenario.telemetry {
        Some(t) => t.every_ticks()?,
        None => DEFAULT_TELEMETRY_EVERY_TICKS,
    })
}

/// `scenario` as a run with a ground station goes (docs/hil.md, "A
/// ground station on the firmware under QEMU"): it needs a route (the
/// firmware's MAVLink endpoint is its route runs'), and it lasts its
/// duration, not ending `settle_s` after the route is done (the ground
/// station may send another mission).
///
/// # Errors
/// A scenario without a route.
fn for_a_ground_station(scenario: &Scenario) -> anyhow::Result<Scenario> {
    let mut scenario = scenario.clone();
    let duration_s = scenario.duration_s;
    match &mut scenario.reference {
        ReferenceSpec::Route(route) => route.settle_s = duration_s,
        _ => anyhow::bail!(
            "--mavlink needs a route scenario or a robot file with a route \
             ([reference] kind = \"route\"): the firmware's MAVLink endpoint runs with its route"
        ),
    }
    Ok(scenario)
}

/// Runs `scenario` with its control tick in the firmware under QEMU (built
/// with the [`firmware_features`] it needs, unless `options.firmware`
/// names an ELF).
///
/// # Errors
/// QEMU missing or failing, the firmware refusing the configuration (or
/// its tag map, or its route), not
/// answering in time, or answering with corrupt or unexpected frames.
pub fn run_hil(
    scenario: &Scenario,
    options: &HilOptions,
    progress: impl FnMut(u64, u64),
) -> anyhow::Result<HilRun> {
    let bridged;
    let scenario = match &options.mavlink {
        Some(_) => {
            bridged = for_a_ground_station(scenario)?;
            &bridged
        }
        None => scenario,
    };
    let setup = scenario.validate()?;
    let configure = wmr_link::Configure {
        telemetry_every_ticks: options.telemetry_every_ticks,
        ..hil_configuration(&setup)?
    };
    let firmware = match &options.firmware {
        Some(path) => path.clone(),
        None => build_firmware_with(None, &firmware_features(&configure.pilot))?,
    };
    ensure!(
        firmware.is_file(),
        "no firmware ELF at {}",
        firmware.display()
    );
    let map = hil_map_chunks(&setup)?;
    let route = hil_route_messages(&setup);
    if options.mavlink.is_some() {
        ensure!(
            options.faults.is_none(),
            "--mavlink and --link-faults cannot be combined: the MAVLink channel is not \
             resent over a faulty link"
        );
    }
    // The ground station's socket first: an address in use is reported
    // before QEMU boots, not after the configuration.
    let bridge = options
        .mavlink
        .as_ref()
        .map(|spec| mavlink::Bridge::open(spec, setup.period_s))
        .transpose()?;
    let mut target = QemuTarget::start(&firmware, options)?;
    target.configure(configure, &map, &route)?;
    if let Some(bridge) = bridge {
        target.attach_bridge(bridge);
    }
    let mut result = run_with_target(scenario, &mut target, progress)?;
    let finished = target
        .finished
        .ok_or_else(|| anyhow::anyhow!("the run ended without the firmware's report"))?;
    let report = HilReport {
        firmware_ticks: finished.ticks,
        peak_stack_bytes: finished.peak_stack_bytes,
        firmware_link: finished.counters.link,
        host_link: target.rx.counters(),
        uart_overruns: finished.counters.uart_overruns,
        repeated_ticks: finished.counters.repeated_ticks,
        stale_ticks: finished.counters.stale_ticks,
        route_done: finished.route_done,
        link_faults: target.fault_report(),
        mavlink: target
            .bridge
            .as_ref()
            .map(|bridge| bridge.report(target.link_silences)),
    };
    if report.mavlink.is_some() {
        // The route report measures the run against the scenario's
        // waypoints and stops, which a ground station may have replaced,
        // paused or stopped: not made (docs/hil.md).
        result.summary.route = None;
    }
    result.summary.hil = Some(report);
    if let Some(raw) = &options.log {
        // QEMU has exited: the log is complete. It is diagnostics, so a
        // failure to decode it is reported, not fatal.
        let text = decode_defmt_log(&firmware, raw)
            .unwrap_or_else(|e| format!("(defmt log not decoded: {e:#})\n"));
        let path = raw.with_extension("log");
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(HilRun {
        result,
        report,
        firmware,
    })
}
