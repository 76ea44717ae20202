//! The robot's flash image: a robot file's configuration as the firmware
//! keeps it in flash (`cargo xtask firmware --robot FILE`).
//!
//! `firmware-sim robot-image FILE` validates the robot file with the core's
//! constructors (as every simulation of it does) and writes the image; the
//! firmware's `build.rs` includes it (`include_bytes!`, env var
//! `WMR_ROBOT_IMAGE`) and the Black Pill board decodes it at power-on in
//! place of its compiled-in defaults. Layout, all little-endian:
//!
//! ```text
//! MAGIC (8 bytes) | IMAGE_VERSION u16 | pilot length u16 | pilot (postcard PilotSpec)
//! | telemetry decimation u16 (a record every N ticks; 0: none)
//! | route kind u8: 0 none, 1 a route
//! | route: postcard RouteSpec (length u16 first; with the route run's
//!          MAVLink endpoint settings and power-on, `MavlinkSettings`),
//!          then RouteSpec::waypoints × postcard Waypoint (each length u16 first)
//! | floor kind u8: 0 grid, 1 tag map
//! | grid: postcard TagGridSpec (length u16 first)
//! | tag map: count u32, then count × (id u64, x f32, y f32), ids strictly increasing
//! ```
//!
//! The tag records stay in flash: [`ImageTags`] looks ids up by binary
//! search over the bytes, with no copy in RAM. A route's waypoints are
//! checked to decode; the board loads them into its `RouteStore` with the
//! core's checks ([`ImageRoute::load_into`]), as the HIL link's session
//! does. Decoding never panics: a malformed image is an [`ImageError`].

use serde::{Deserialize, Serialize};
use wmr_core::devices::tag_grid::TagGridSpec;
use wmr_core::devices::{TagGrid, TagId, TagLocator};
use wmr_core::geometry::Vec2;
use wmr_core::pilot::spec::{PilotSpec, SpecError};
use wmr_core::reference::route::{RouteLimits, Waypoint};

use crate::session::RouteStore;
use crate::{RouteRefusal, RouteSpec};

/// The image's first bytes.
pub const MAGIC: [u8; 8] = *b"WMRROBOT";
/// Bump when the layout (or [`PilotSpec`]'s shape) changes (what each
/// version changed: `CHANGELOG.md`, "Robot image versions").
pub const IMAGE_VERSION: u16 = 6;
/// Bytes of one tag record: id `u64`, `x`, `y` `f32`.
pub const TAG_RECORD_BYTES: usize = 16;

/// Why an image was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImageError {
    /// No [`MAGIC`] at the start.
    Magic,
    /// Another [`IMAGE_VERSION`] (the image's).
    Version(u16),
    /// Shorter than its lengths say, or bytes left over.
    Length,
    /// The pilot or the grid does not decode.
    Encoding,
    /// A floor kind other than 0 or 1.
    FloorKind,
    /// A route kind other than 0 or 1, or a route or waypoint that does
    /// not decode.
    Route,
    /// Tag ids not strictly increasing, wider than 40 bits, or a position
    /// not finite.
    Tags,
    /// The core refused the pilot or the grid.
    Spec(SpecError),
    /// The board cannot run the control period (the Black Pill: 1 to
    /// 100 ms, and its 50 ms watchdog must outlast three periods).
    Period,
}

impl core::fmt::Display for ImageError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Magic => f.write_str("not a robot image (no WMRROBOT magic)"),
            Self::Version(v) => write!(
                f,
                "robot image version {v}, this firmware reads {IMAGE_VERSION}"
            ),
            Self::Length => f.write_str("robot image truncated or over-long"),
            Self::Encoding => f.write_str("robot image: the pilot or grid does not decode"),
            Self::FloorKind => f.write_str("robot image: unknown floor kind"),
            Self::Route => f.write_str("robot image: the route does not decode"),
            Self::Tags => f.write_str(
                "robot image: tag ids must be 40-bit and strictly increasing, positions finite",
            ),
            Self::Spec(e) => write!(f, "robot image: {e}"),
            Self::Period => f.write_str("robot image: the board cannot run this control period"),
        }
    }
}

impl core::error::Error for ImageError {}

/// The floor of an image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ImageFloor<'a> {
    /// A tag grid.
    Grid(TagGrid),
    /// A tag map, its records in the image.
    Map(ImageTags<'a>),
}

impl TagLocator for ImageFloor<'_> {
    fn locate(&self, id: TagId) -> Option<Vec2> {
        match self {
            Self::Grid(grid) => grid.locate(id),
            Self::Map(tags) => tags.locate(id),
        }
    }
}

/// A tag map's records inside an image (checked by [`decode`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageTags<'a> {
    records: &'a [u8],
}

impl<'a> ImageTags<'a> {
    /// Number of tags.
    #[must_use]
    pub fn len(&self) -> usize {
        self.records.len() / TAG_RECORD_BYTES
    }

    /// Whether there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Tag `i`: its id and position.
    #[must_use]
    pub fn get(&self, i: usize) -> Option<(TagId, Vec2)> {
        let at = i.checked_mul(TAG_RECORD_BYTES)?;
        let r = self.records.get(at..at.checked_add(TAG_RECORD_BYTES)?)?;
        let id = u64::from_le_bytes(r.get(0..8)?.try_into().ok()?);
        let x = f32::from_le_bytes(r.get(8..12)?.try_into().ok()?);
        let y = f32::from_le_bytes(r.get(12..16)?.try_into().ok()?);
        Some((TagId(id), Vec2::new(x, y)))
    }

    /// Every tag, in id order.
    pub fn iter(&self) -> impl Iterator<Item = (TagId, Vec2)> + 'a {
        let tags = *self;
        (0..tags.len()).filter_map(move |i| tags.get(i))
    }
}

impl TagLocator for ImageTags<'_> {
    /// Binary search over the sorted ids: O(log N), no allocation.
    fn locate(&self, id: TagId) -> Option<Vec2> {
        let (mut lo, mut hi) = (0, self.len());
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            let (at, position) = self.get(mid)?;
            match at.0.cmp(&id.0) {
                core::cmp::Ordering::Equal => return Some(position),
                core::cmp::Ordering::Less => lo = mid + 1,
                core::cmp::Ordering::Greater => hi = mid,
            }
        }
        None
    }
}

/// A route inside an image (its waypoints checked to decode by
/// [`decode`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageRoute<'a> {
    /// The route's count, limits, options and start.
    pub spec: RouteSpec,
    /// `spec.waypoints` length-prefixed postcard waypoints.
    waypoints: &'a [u8],
}

impl<'a> ImageRoute<'a> {
    /// The waypoints, in route order.
    pub fn waypoints(&self) -> impl Iterator<Item = Waypoint> + 'a {
        let mut rest = self.waypoints;
        core::iter::from_fn(move || {
            let (len, tail) = u16_at(rest).ok()?;
            let (bytes, tail) = split(tail, usize::from(len)).ok()?;
            rest = tail;
            postcard::from_bytes(bytes).ok()
        })
    }

    /// Loads the route into `store` with the core's checks, as a HIL
    /// session loads one ([`RouteStore::begin`], [`RouteStore::push`],
    /// [`RouteStore::finish`]) at the control period `period_s`.
    ///
    /// Returns the validated limits (a MAVLink run's, `MavlinkRun::activate`).
    ///
    /// # Errors
    /// The first [`RouteRefusal`]: the count, a limit or an option, or
    /// the planner's refusal naming the waypoint and its key.
    pub fn load_into(
        &self,
        store: &mut RouteStore,
        period_s: f32,
    ) -> Result<RouteLimits, RouteRefusal> {
        let limits = store.begin(&self.spec)?;
        for w in self.waypoints() {
            store.push(w)?;
        }
        store.finish(&limits, self.spec.start, period_s)?;
        Ok(limits)
    }
}

/// A decoded image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotImage<'a> {
    /// The pilot.
    pub pilot: PilotSpec,
    /// A telemetry record every this many ticks (0: none).
    pub telemetry_every_ticks: u16,
    /// The route the robot follows instead of the pilot's trajectory, if
    /// any.
    pub route: Option<ImageRoute<'a>>,
    /// The floor.
    pub floor: ImageFloor<'a>,
}

fn split(bytes: &[u8], n: usize) -> Result<(&[u8], &[u8]), ImageError> {
    if bytes.len() < n {
        return Err(ImageError::Length);
    }
    Ok(bytes.split_at(n))
}

fn u16_at(bytes: &[u8]) -> Result<(u16, &[u8]), ImageError> {
    let (head, rest) = split(bytes, 2)?;
    let v = head.try_into().map_err(|_| ImageError::Length)?;
    Ok((u16::from_le_bytes(v), rest))
}

/// Decodes and checks an image: the tags' order, width and positions,
/// the grid with the core's constructor (the pilot is the caller's to
/// build, with [`PilotSpec::build`]).
///
/// # Errors
/// The first [`ImageError`].
pub fn decode(bytes: &[u8]) -> Result<RobotImage<'_>, ImageError> {
    let (magic, rest) = split(bytes, MAGIC.len())?;
    if magic != MAGIC {
        return Err(ImageError::Magic);
    }
    let (version, rest) = u16_at(rest)?;
    if version != IMAGE_VERSION {
        return Err(ImageError::Version(version));
    }
    let (pilot_len, rest) = u16_at(rest)?;
    let (pilot, rest) = split(rest, usize::from(pilot_len))?;
    let pilot: PilotSpec = postcard::from_bytes(pilot).map_err(|_| ImageError::Encoding)?;
    let (telemetry_every_ticks, rest) = u16_at(rest)?;
    let (route_kind, rest) = split(rest, 1)?;
    let (route, rest) = match route_kind {
        [0] => (None, rest),
        [1] => {
            let (len, rest) = u16_at(rest)?;
            let (spec, rest) = split(rest, usize::from(len))?;
            let spec: RouteSpec = postcard::from_bytes(spec).map_err(|_| ImageError::Route)?;
            let mut end = rest;
            for _ in 0..spec.waypoints {
                let (len, tail) = u16_at(end)?;
                let (w, tail) = split(tail, usize::from(len))?;
                let _: Waypoint = postcard::from_bytes(w).map_err(|_| ImageError::Route)?;
                end = tail;
            }
            let used = rest.len() - end.len();
            let (waypoints, rest) = split(rest, used)?;
            (Some(ImageRoute { spec, waypoints }), rest)
        }
        _ => return Err(ImageError::Route),
    };
    let (kind, rest) = split(rest, 1)?;
    let floor = match kind {
        [0] => {
            let (len, rest) = u16_at(rest)?;
            let (grid, rest) = split(rest, usize::from(len))?;
            if !rest.is_empty() {
                return Err(ImageError::Length);
            }
            let grid: TagGridSpec = postcard::from_bytes(grid).map_err(|_| ImageError::Encoding)?;
            ImageFloor::Grid(grid.build().map_err(|e| ImageError::Spec(e.into()))?)
        }
        [1] => {
            let (count, records) = split(rest, 4)?;
            let count = u32::from_le_bytes(count.try_into().map_err(|_| ImageError::Length)?);
            let expected = usize::try_from(count)
                .ok()
                .and_then(|n| n.checked_mul(TAG_RECORD_BYTES))
                .ok_or(ImageError::Length)?;
            if records.len() != expected {
                return Err(ImageError::Length);
            }
            let tags = ImageTags { records };
            let mut last: Option<u64> = None;
            for (id, p) in tags.iter() {
                let increasing = last.is_none_or(|l| id.0 > l);
                if id.0 > TagId::MASK || !increasing || !p.x.is_finite() || !p.y.is_finite() {
                    return Err(ImageError::Tags);
                }
                last = Some(id.0);
            }
            ImageFloor::Map(tags)
        }
        _ => return Err(ImageError::FloorKind),
    };
    Ok(RobotImage {
        pilot,
        telemetry_every_ticks,
        route,
        floor,
    })
}

/// The floor to encode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ImageFloorSpec<'a> {
    /// A tag grid.
    Grid(TagGridSpec),
    /// A tag map: `(id, [x, y])`, sorted by id.
    Map(&'a [(TagId, [f32; 2])]),
}

/// Bytes a route section takes at most beyond its kind byte: the spec and
/// [`ROUTE_CAPACITY`](wmr_core::reference::route::ROUTE_CAPACITY)
/// waypoints, each with its length (a waypoint is at most 23 B of
/// postcard).
const MAX_ROUTE_BYTES: usize = 2 + 64 + wmr_core::reference::route::ROUTE_CAPACITY * (2 + 32);

/// Bytes an image of `tags` mapped tags (and a route, if it has one)
/// takes at most.
#[must_use]
pub const fn max_image_bytes(tags: usize) -> usize {
    MAGIC.len()
        + 2
        + 2
        + crate::MAX_FRAME_BYTES
        + 2
        + 1
        + MAX_ROUTE_BYTES
        + 1
        + 4
        + tags * TAG_RECORD_BYTES
}

struct Writer<'a> {
    out: &'a mut [u8],
    at: usize,
}

impl Writer<'_> {
    fn put(&mut self, bytes: &[u8]) -> Result<(), ImageError> {
        let end = self.at.checked_add(bytes.len()).ok_or(ImageError::Length)?;
        self.out
            .get_mut(self.at..end)
            .ok_or(ImageError::Length)?
            .copy_from_slice(bytes);
        self.at = end;
        Ok(())
    }

    /// `value` in postcard after its `u16` length.
    fn put_postcard<T: Serialize>(&mut self, value: &T) -> Result<(), ImageError> {
        let mut buf = [0_u8; crate::MAX_FRAME_BYTES];
        let used = postcard::to_slice(value, &mut buf).map_err(|_| ImageError::Encoding)?;
        let len = u16::try_from(used.len()).map_err(|_| ImageError::Encoding)?;
        self.put(&len.to_le_bytes())?;
        let used = &*used;
        self.put(used)
    }
}

/// Encodes an image into `out` (at least [`max_image_bytes`] long for the
/// tag count) and checks it as the firmware will ([`decode`]); returns
/// its length. `telemetry_every_ticks`: a telemetry record every this many
/// ticks (0: none). `route`: its spec and waypoints (the spec's count is
/// set from them); the core's checks of it are the board's, at start-up
/// ([`ImageRoute::load_into`]), and the robot file's, before.
///
/// # Errors
/// [`ImageError::Length`] if `out` is too short, [`ImageError::Route`]
/// for more waypoints than a `u8` counts, or what [`decode`] finds.
pub fn encode(
    pilot: &PilotSpec,
    telemetry_every_ticks: u16,
    route: Option<(&RouteSpec, &[Waypoint])>,
    floor: &ImageFloorSpec<'_>,
    out: &mut [u8],
) -> Result<usize, ImageError> {
    let mut w = Writer { out, at: 0 };
    w.put(&MAGIC)?;
    w.put(&IMAGE_VERSION.to_le_bytes())?;
    w.put_postcard(pilot)?;
    w.put(&telemetry_every_ticks.to_le_bytes())?;
    match route {
        None => w.put(&[0])?,
        Some((spec, waypoints)) => {
            w.put(&[1])?;
            let count = u8::try_from(waypoints.len()).map_err(|_| ImageError::Route)?;
            w.put_postcard(&RouteSpec {
                waypoints: count,
                ..*spec
            })?;
            for waypoint in waypoints {
                w.put_postcard(waypoint)?;
            }
        }
    }
    match floor {
        ImageFloorSpec::Grid(grid) => {
            w.put(&[0])?;
            w.put_postcard(grid)?;
        }
        ImageFloorSpec::Map(tags) => {
            w.put(&[1])?;
            let count = u32::try_from(tags.len()).map_err(|_| ImageError::Tags)?;
            w.put(&count.to_le_bytes())?;
            for (id, [x, y]) in *tags {
                w.put(&id.0.to_le_bytes())?;
                w.put(&x.to_le_bytes())?;
                w.put(&y.to_le_bytes())?;
            }
        }
    }
    let len = w.at;
    let written = w.out.get(..len).ok_or(ImageError::Length)?;
    decode(written)?;
    Ok(len)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> PilotSpec {
        let crate::HostMessage::Configure(c) = crate::tests::configure() else {
            unreachable!("configure() is a Configure")
        };
        let mut pilot = c.pilot;
        // The wheel-speed observer travels in the image too.
        pilot.drive.speed_observer = Some(wmr_core::drive::spec::SpeedObserverSpec {
            mass_kg: 4.0,
            yaw_inertia_kg_m2: 0.08,
            wheel_inertia_kg_m2: 0.0,
            stall_torque_nm: 0.6,
            no_load_speed_rad_s: 20.0,
            lambda_per_s: 5.0,
            friction_gain: 0.01,
            disturbance_gain: 0.1,
        });
        pilot
    }

    #[test]
    fn an_image_round_trips_and_finds_its_tags() {
        let tags = [
            (TagId(3), [1.0, 2.0]),
            (TagId(0x01_0000_0007), [-5.0, 3.5]),
            (TagId(TagId::MASK), [0.0, -1.0]),
        ];
        let mut buf = [0_u8; max_image_bytes(3)];
        let n = encode(&spec(), 7, None, &ImageFloorSpec::Map(&tags), &mut buf).unwrap();
        let image = decode(&buf[..n]).unwrap();
        assert_eq!(image.pilot, spec());
        assert_eq!(image.telemetry_every_ticks, 7);
        let ImageFloor::Map(map) = image.floor else {
            panic!("a map")
        };
        assert_eq!(map.len(), 3);
        for (id, [x, y]) in tags {
            assert_eq!(image.floor.locate(id), Some(Vec2::new(x, y)));
        }
        assert_eq!(image.floor.locate(TagId(4)), None);
        // Truncated, unsorted or with a bad magic: refused, never a panic.
        assert_eq!(decode(&buf[..n - 1]), Err(ImageError::Length));
        let mut bad = buf;
        bad[0] = b'X';
        assert_eq!(decode(&bad[..n]), Err(ImageError::Magic));
        let unsorted = [tags[1], tags[0]];
        assert_eq!(
            encode(&spec(), 7, None, &ImageFloorSpec::Map(&unsorted), &mut buf),
            Err(ImageError::Tags)
        );
        for len in 0..n {
            let _ = decode(&buf[..len]);
        }
    }

    #[test]
    fn a_grid_image_round_trips() {
        let grid = TagGridSpec {
            origin_m: [-6.0, -6.5],
            spacing_m: 0.1,
            rows: 130,
            columns: 120,
        };
        let mut buf = [0_u8; max_image_bytes(0)];
        let n = encode(&spec(), 10, None, &ImageFloorSpec::Grid(grid), &mut buf).unwrap();
        let image = decode(&buf[..n]).unwrap();
        assert_eq!(image.floor, ImageFloor::Grid(grid.build().unwrap()));
    }

    /// A route travels in the image: decoded as encoded, loaded into a
    /// `RouteStore` through the core's checks; a route the core refuses
    /// is refused at the load naming the waypoint and key (the image
    /// itself decodes); a waypoint that does not decode, or a route kind
    /// other than 0 or 1, is an image error.
    #[test]
    fn an_image_carries_a_route_loaded_through_the_cores_checks() {
        use wmr_core::pilot::route::{RouteOptions, RouteStart};
        use wmr_core::reference::route::{RouteError, RouteLimitsSpec, WaypointKey};
        let route = RouteSpec {
            waypoints: 0,
            limits: RouteLimitsSpec {
                max_speed_m_s: 0.3,
                max_tangential_accel_m_s2: 0.5,
                max_lateral_accel_m_s2: 0.5,
                blend_deviation_m: 0.02,
                pivot_threshold_rad: 0.5,
                pivot_rate_rad_s: 1.0,
                pivot_accel_rad_s2: 2.0,
            },
            options: RouteOptions::default().spec(),
            start: RouteStart::FromFirstFix,
            mavlink: crate::MavlinkSettings {
                system_id: 7,
                telemetry_period_ms: 100,
                link_timeout_ms: 5_000,
                origin_e7: Some([473_977_420, 85_455_940]),
                power_on: crate::PowerOn::Wait,
                ..crate::MavlinkSettings::default()
            },
        };
        let waypoints = [
            Waypoint::stop(0.0, 0.0, 0.0),
            Waypoint::pass(0.5, 0.1).with_speed_limit(0.2),
            Waypoint::stop(1.0, 0.0, 0.5).facing(1.5),
        ];
        let grid = TagGridSpec {
            origin_m: [-6.0, -6.5],
            spacing_m: 0.1,
            rows: 130,
            columns: 120,
        };
        let mut buf = std::vec![0_u8; max_image_bytes(0)];
        let n = encode(
            &spec(),
            10,
            Some((&route, &waypoints)),
            &ImageFloorSpec::Grid(grid),
            &mut buf,
        )
        .unwrap();
        let image = decode(&buf[..n]).unwrap();
        assert_eq!(image.floor, ImageFloor::Grid(grid.build().unwrap()));
        let read = image.route.unwrap();
        assert_eq!(read.spec.waypoints, 3);
        assert_eq!(read.spec.start, RouteStart::FromFirstFix);
        // The MAVLink endpoint's settings and power-on travel with it.
        assert_eq!(read.spec.mavlink, route.mavlink);
        assert_eq!(read.spec.mavlink.power_on, crate::PowerOn::Wait);
        assert_eq!(
            read.spec.mavlink.endpoint_spec().origin_e7,
            Some((473_977_420, 85_455_940))
        );
        assert!(read.waypoints().eq(waypoints.iter().copied()));
        let mut store = std::boxed::Box::new(RouteStore::new());
        read.load_into(&mut store, 0.01).unwrap();
        assert_eq!(store.waypoints().as_slice(), &waypoints[..]);
        assert!(store.follower().unwrap().status().pending);

        // The core refuses a waypoint: the image decodes, the load names it.
        let mut bad = waypoints;
        bad[1] = Waypoint::pass(0.5, f32::NAN);
        let n = encode(
            &spec(),
            10,
            Some((&route, &bad)),
            &ImageFloorSpec::Grid(grid),
            &mut buf,
        )
        .unwrap();
        let image = decode(&buf[..n]).unwrap();
        assert_eq!(
            image.route.unwrap().load_into(&mut store, 0.01),
            Err(RouteRefusal::Route(RouteError::NotFinite {
                index: 1,
                key: WaypointKey::Position
            }))
        );
        assert_eq!(
            std::format!(
                "{}",
                RouteRefusal::Route(RouteError::NotFinite {
                    index: 1,
                    key: WaypointKey::Position
                })
            ),
            "waypoint 1: position_m must be finite"
        );
        // Every truncation is refused, never a panic; a bad route kind too.
        for len in 0..n {
            assert!(decode(&buf[..len]).is_err());
        }
        let kind_at = MAGIC.len() + 2 + 2 + usize::from(u16::from_le_bytes([buf[10], buf[11]])) + 2;
        assert_eq!(buf[kind_at], 1);
        buf[kind_at] = 2;
        assert_eq!(decode(&buf[..n]), Err(ImageError::Route));
    }
}
