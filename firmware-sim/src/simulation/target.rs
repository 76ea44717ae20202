//! The control tick run elsewhere: the [`TargetLink`] a remote robot (the
//! firmware under QEMU) answers on, and the configuration it needs.

use wmr_core::pilot::spec::TagGridSpec;
use wmr_link::{Configure, Diagnostics, TickInput, TickOutput};

use crate::scenario::{PlantSetup, PositionSetup, Setup};

/// A robot whose control tick runs elsewhere (the firmware under QEMU,
/// over the HIL link): it gets the devices' readings, answers with what it
/// drove.
pub trait TargetLink {
    /// One lock-step exchange.
    ///
    /// # Errors
    /// The link failed (timeout, corrupt or unexpected answer).
    fn tick(&mut self, input: &TickInput) -> anyhow::Result<TickOutput>;

    /// Ends the run; returns the target's final counters.
    ///
    /// # Errors
    /// The link failed.
    fn finish(&mut self) -> anyhow::Result<Diagnostics>;
}

/// What the firmware must be configured with to run `setup` (diff-drive
/// plant with a reader only: the firmware's devices are encoders, motors
/// and the reader's UART).
///
/// # Errors
/// A scenario whose position source or plant no device delivers.
pub fn hil_configuration(setup: &Setup) -> anyhow::Result<Configure> {
    let (
        PlantSetup::DiffDrive {
            pwm_max_duty,
            pilot_spec,
            ..
        },
        PositionSetup::Reader(floor, _),
    ) = (setup.plant, &setup.position)
    else {
        anyhow::bail!(
            "hardware-in-the-loop runs need plant.kind = \"diff_drive\" and position.kind = \"reader\" \
             (the firmware senses through encoders and the RFID reader's UART only)"
        );
    };
    let Some(floor) = floor.grid() else {
        anyhow::bail!(
            "hardware-in-the-loop runs need a tag grid: the HIL link's Configure message carries \
             the firmware's floor as a grid (TagGridSpec), not a tag map (floor.kind = \"tag_map\"); \
             simulate the robot with `firmware-sim run` or `sweep`, or flash it with \
             `cargo xtask firmware --robot FILE`"
        );
    };
    Ok(Configure {
        protocol: wmr_link::PROTOCOL_VERSION,
        pilot: pilot_spec,
        grid: TagGridSpec::of(floor.grid()),
        pwm_max_duty,
        // Off: the caller asks for telemetry (`HilOptions`).
        telemetry_every_ticks: 0,
    })
}

#[cfg(test)]
#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::{Scenario, SpeedObserverSpec};

    #[test]
    fn the_link_carries_the_speed_observer() {
        // Protocol 10 sends it in the drive's spec: the firmware builds the
        // same observer from the same numbers.
        let mut full = Scenario::embedded("figure_eight_rfid_full_stack").unwrap();
        let plain = hil_configuration(&full.validate().unwrap()).unwrap();
        assert_eq!(plain.pilot.drive.speed_observer, None);
        let mut drive = full.drive.unwrap_or_default();
        drive.speed_observer = Some(SpeedObserverSpec {
            mass_kg: 4.0,
            yaw_inertia_kg_m2: 0.08,
            wheel_inertia_kg_m2: 0.0,
            stall_torque_nm: 0.6,
            lambda_per_s: 5.0,
            friction_gain: 0.01,
            disturbance_gain: 0.1,
        });
        full.drive = Some(drive);
        let setup = full.validate().unwrap();
        let configure = hil_configuration(&setup).unwrap();
        let sent = configure.pilot.drive.speed_observer.unwrap();
        assert_eq!(sent.mass_kg, 4.0);
        assert_eq!(sent.no_load_speed_rad_s, 20.0);
        let PlantSetup::DiffDrive { pilot, .. } = setup.plant else {
            panic!("diff drive")
        };
        assert_eq!(configure.pilot.build().unwrap(), pilot);
    }
}
