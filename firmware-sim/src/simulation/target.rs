//! The control tick run elsewhere: the [`TargetLink`] a remote robot (the
//! firmware under QEMU) answers on, and the configuration it needs.

use std::cell::RefCell;
use wmr_core::devices::tag_grid::TagGridSpec;

use wmr_core::pilot::route::RouteFollower;
use wmr_link::proxy::ProxyBus;
use wmr_link::session::{LinkTagMap, MavlinkStore, RouteStore, Session};
use wmr_link::{
    Configure, Diagnostics, FloorSpec, HostMessage, LinkCounters, MAP_CAPACITY, MAP_CHUNK_TAGS,
    MapChunk, MapTag, MavlinkIn, MavlinkOut, TargetMessage, TickInput, TickOutput,
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

    /// The link's MAVLink channel, when the run carries one (a ground
    /// station bridged to it: `firmware-sim hil --mavlink`): the
    /// exchanges made before each tick, which the host's copy of the
    /// session is fed too ([`MavlinkLog`]). `None` (the default): the run
    /// sends no MAVLink message.
    fn mavlink_log(&mut self) -> Option<&mut MavlinkLog> {
        None
    }

    /// The run is to end before its next tick (Ctrl-C): the loop stops,
    /// the target is finished and the run reported up to here. `false`
    /// by default.
    fn stop_requested(&self) -> bool {
        false
    }
}

/// The MAVLink messages a remote run sends its target between ticks, and
/// how the host's copy of the firmware's session (`RouteShadow`)
/// answered the same: the copy is fed each message before the tick the
/// target got it before, so that its route (the run's route status and
/// end) follows what the ground station did to the target's, and each of
/// its answers is compared with the target's, byte for byte.
#[derive(Debug, Clone, Default)]
pub struct MavlinkLog {
    /// The exchanges made before the tick now being run, in order: the
    /// host's message and the target's answer (the rig takes them).
    pub exchanges: Vec<(MavlinkIn, MavlinkOut)>,
    /// Answers the copy was asked for.
    pub compared: u64,
    /// Answers of the copy that differ from the target's.
    pub mismatches: u32,
    /// The tick before which the first differing answer came.
    pub first_mismatch_tick: Option<u32>,
}

/// What the firmware must be configured with to run `setup` (diff-drive
/// plant with a reader only: the firmware's devices are encoders, motors
/// and the reader's UART). A tag-map floor is announced
/// ([`FloorSpec::Map`]); its tags follow in [`hil_map_chunks`], and a
/// route's messages in [`hil_route_messages`].
///
/// # Errors
/// A scenario whose position source or plant no device delivers, or a
/// tag map larger than the firmware holds ([`MAP_CAPACITY`]).
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

/// The messages that load `setup`'s route once the firmware is
/// configured (none for an analytic reference): the announcement and the
/// waypoints in chunks ([`wmr_link::route_messages`]), each sent after the
/// answer to the one before.
#[must_use]
pub fn hil_route_messages(setup: &Setup) -> Vec<HostMessage> {
    setup.route.as_ref().map_or_else(Vec::new, |route| {
        let spec = route.spec();
        wmr_link::route_messages(
            &route.waypoints,
            spec.limits,
            &route.options,
            spec.start,
            spec.mavlink,
        )
        .collect()
    })
}

/// Storage a [`RouteShadow`] lends its session: the link's proxies, tag
/// map and route store, as the QEMU board holds them (the route store is
/// about 24 KB: on the heap), and, for a run that carries MAVLink, the
/// endpoint's store.
pub(super) struct ShadowStorage {
    bus: ProxyBus,
    map: RefCell<LinkTagMap>,
    route: Box<RouteStore>,
    mavlink: Option<Box<MavlinkStore>>,
}

impl ShadowStorage {
    /// With `mavlink`, a MAVLink store configured as the QEMU board's
    /// (`firmware/src/board/qemu.rs`, `mavlink_store`: the endpoint's
    /// default configuration, the idle route limits replaced by the
    /// run's); a difference would show as answers that differ
    /// ([`MavlinkLog::mismatches`]).
    pub(super) fn new(mavlink: bool) -> anyhow::Result<Self> {
        let mavlink = if mavlink {
            let config = wmr_mavlink::EndpointConfig::new(&wmr_mavlink::EndpointSpec::default())
                .map_err(|e| anyhow::anyhow!("the MAVLink endpoint's configuration: {e}"))?;
            let limits = wmr_core::reference::route::RouteLimits::new(&MavlinkStore::IDLE_LIMITS)
                .map_err(|e| anyhow::anyhow!("the idle route limits: {e:?}"))?;
            Some(Box::new(MavlinkStore::new(config, limits)))
        } else {
            None
        };
        Ok(Self {
            bus: ProxyBus::new(),
            map: RefCell::new(LinkTagMap::new()),
            route: Box::new(RouteStore::new()),
            mavlink,
        })
    }
}

/// The firmware's session (`wmr_link::session`, the code the QEMU board
/// runs) on the host, beside a HIL run of a route, fed the same messages.
/// The link's `Ticked` carries no route status; the run takes it from
/// here: where the route starts (the record's reference before it),
/// when it is done (the run ends `settle_s` later) and the follower the
/// route's report is made from. The records themselves are the
/// firmware's answers.
pub(super) struct RouteShadow<'s> {
    session: Session<'s>,
}

impl<'s> RouteShadow<'s> {
    /// A session configured as the firmware is for `setup` (none without a
    /// route).
    ///
    /// # Errors
    /// The session refusing the configuration, its map or its route (the
    /// firmware refuses the same).
    pub(super) fn new(
        setup: &Setup,
        storage: &'s mut ShadowStorage,
    ) -> anyhow::Result<Option<Self>> {
        if setup.route.is_none() {
            return Ok(None);
        }
        let mut session = Session::new(&storage.bus, &storage.map, &mut storage.route);
        if let Some(store) = storage.mavlink.as_deref_mut() {
            session.lend_mavlink(store);
        }
        let messages = core::iter::once(HostMessage::Configure(hil_configuration(setup)?))
            .chain(
                hil_map_chunks(setup)?
                    .into_iter()
                    .map(HostMessage::MapChunk),
            )
            .chain(hil_route_messages(setup));
        let mut last = None;
        for message in messages {
            let (answer, _) = session.handle(&message, LinkCounters::default(), || 0);
            if let TargetMessage::Refused(why) = answer {
                anyhow::bail!("the host's copy of the firmware's session refused the run: {why}");
            }
            last = Some(answer);
        }
        anyhow::ensure!(
            last == Some(TargetMessage::Configured) && session.is_configured(),
            "the host's copy of the firmware's session was not configured: {last:?}"
        );
        Ok(Some(Self { session }))
    }

    /// Runs the tick the firmware was sent.
    pub(super) fn tick(&mut self, input: &TickInput) {
        let message = HostMessage::Tick(input.clone());
        let _ = self.session.handle(&message, LinkCounters::default(), || 0);
    }

    /// Handles a MAVLink message the firmware was sent; returns the
    /// session's answer.
    pub(super) fn mavlink(&mut self, message: &MavlinkIn) -> Option<MavlinkOut> {
        let message = HostMessage::Mavlink(*message);
        match self.session.handle(&message, LinkCounters::default(), || 0) {
            (TargetMessage::Mavlink(out), _) => Some(out),
            _ => None,
        }
    }

    /// The route's follower.
    pub(super) fn follower(&self) -> Option<&RouteFollower> {
        self.session.route_follower()
    }
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
