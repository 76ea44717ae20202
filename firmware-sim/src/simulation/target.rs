//! The control tick run elsewhere: the [`TargetLink`] a remote robot (the
//! firmware under QEMU) answers on, and the configuration it needs.

use wmr_core::devices::tag_grid::TagGridSpec;
use wmr_link::{
    Configure, Diagnostics, FloorSpec, MAP_CAPACITY, MAP_CHUNK_TAGS, MapChunk, MapTag, TickInput,
    TickOutput,
};

use crate::scenario::{PlantSetup, PositionSetup, Setup};
use crate::tags::Floor;

// Every tag map a robot file may hold (the Black Pill's flash table) fits
// the HIL firmware's: a robot runs under HIL whatever its floor.
const _: () = assert!(crate::tags::MAX_MAP_TAGS <= MAP_CAPACITY);

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
/// and the reader's UART). A tag-map floor is announced
/// ([`FloorSpec::Map`]); its tags follow in [`hil_map_chunks`].
///
/// # Errors
/// A route (which the link does not carry yet), a scenario whose position
/// source or plant no device delivers, or a tag map larger than the
/// firmware holds ([`MAP_CAPACITY`]).
pub fn hil_configuration(setup: &Setup) -> anyhow::Result<Configure> {
    // The link's `Configure` carries an analytic reference only.
    if setup.route.is_some() {
        anyhow::bail!(
            "routes do not cross the HIL link yet (reference.kind = \"route\"): the firmware \
             is configured with an analytic reference only; run the route with `firmware-sim run`"
        );
    }
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
    let floor = match floor {
        Floor::Grid(grid) => FloorSpec::Grid(TagGridSpec::of(grid.grid())),
        Floor::Map(map) => {
            let tags = u16::try_from(map.len())
                .ok()
                .filter(|&n| usize::from(n) <= MAP_CAPACITY);
            let Some(tags) = tags else {
                anyhow::bail!(
                    "a tag map of {} tags: the HIL firmware (QEMU board) holds at most \
                     {MAP_CAPACITY} (its static table)",
                    map.len()
                );
            };
            FloorSpec::Map { tags }
        }
    };
    Ok(Configure {
        protocol: wmr_link::PROTOCOL_VERSION,
        pilot: pilot_spec,
        floor,
        pwm_max_duty,
        // Off: the caller asks for telemetry (`HilOptions`).
        telemetry_every_ticks: 0,
    })
}

/// The tag map the firmware loads after `Configure` to run `setup`, in the
/// link's chunks (none for a grid): the robot's own table
/// (`crate::tags::MapTable`, the `f32` positions the host run looks up),
/// in increasing id order, [`MAP_CHUNK_TAGS`] tags a chunk.
///
/// # Errors
/// As [`hil_configuration`].
pub fn hil_map_chunks(setup: &Setup) -> anyhow::Result<Vec<MapChunk>> {
    let FloorSpec::Map { .. } = hil_configuration(setup)?.floor else {
        return Ok(Vec::new());
    };
    let PositionSetup::Reader(Floor::Map(map), _) = &setup.position else {
        anyhow::bail!("a tag map announced without a tag-map floor");
    };
    let tags: Vec<MapTag> = map
        .table()
        .iter()
        .map(|(id, p)| MapTag {
            id: id.0,
            position_m: [p.x, p.y],
        })
        .collect();
    tags.chunks(MAP_CHUNK_TAGS)
        .enumerate()
        .map(|(i, chunk)| {
            Ok(MapChunk {
                // At most `MAP_CAPACITY` tags (checked above): fits.
                first: u16::try_from(i * MAP_CHUNK_TAGS)?,
                tags: heapless::Vec::from_slice(chunk)
                    .map_err(|_| anyhow::anyhow!("a map chunk too long"))?,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::{Scenario, SpeedObserverSpec};

    #[test]
    fn the_link_carries_the_speed_observer() {
        // The link sends it in the drive's spec: the firmware builds the
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

    /// A tag-map robot (`robots/circle_surveyed.toml`) is announced with
    /// its size, and its chunks carry the host robot's table whole, in
    /// increasing id order, each starting where the last ended; a grid
    /// robot's floor is all in `Configure`.
    #[test]
    fn a_tag_map_follows_configure_in_chunks() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("..")
            .join("robots")
            .join("circle_surveyed.toml");
        let setup = Scenario::from_file(&path).unwrap().validate().unwrap();
        let configure = hil_configuration(&setup).unwrap();
        assert_eq!(configure.floor, FloorSpec::Map { tags: 364 });
        let chunks = hil_map_chunks(&setup).unwrap();
        let PositionSetup::Reader(Floor::Map(map), _) = &setup.position else {
            panic!("a tag map")
        };
        let sent: Vec<(u64, [f32; 2])> = chunks
            .iter()
            .flat_map(|c| c.tags.iter().map(|t| (t.id, t.position_m)))
            .collect();
        let table: Vec<(u64, [f32; 2])> = map
            .table()
            .iter()
            .map(|(id, p)| (id.0, [p.x, p.y]))
            .collect();
        assert_eq!(sent, table);
        assert!(sent.windows(2).all(|w| w[0].0 < w[1].0));
        let mut next = 0;
        for chunk in &chunks {
            assert_eq!(usize::from(chunk.first), next);
            assert!(!chunk.tags.is_empty());
            next += chunk.tags.len();
        }
        assert_eq!(chunks.len(), 364_usize.div_ceil(MAP_CHUNK_TAGS));

        let grid = Scenario::embedded("figure_eight_rfid_full_stack")
            .unwrap()
            .validate()
            .unwrap();
        assert!(matches!(
            hil_configuration(&grid).unwrap().floor,
            FloorSpec::Grid(_)
        ));
        assert!(hil_map_chunks(&grid).unwrap().is_empty());
    }
}
