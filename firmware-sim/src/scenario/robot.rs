//! The robot file (`robot.toml`): one robot, described once, for the
//! simulator (`run`, `hil`, `sweep`) and for the firmware's flash image
//! (`cargo xtask firmware --robot FILE`).
//!
//! A robot file holds the tables of a scenario that describe the robot
//! rather than the experiment: its geometry, encoders and motors
//! (`[plant]`, `kind = "diff_drive"`), drive limits and speed loops
//! (`[drive]`, with `[drive.speed_observer]`), law and gains
//! (`[controller]`), paper 001's observer (`[observer]`), the estimator
//! (`[estimator]`), the failsafe (`[failsafe]`), its RFID reader
//! (`[reader]`), the floor it runs on (`[floor]`: a tag grid, or a tag
//! map file of `id,x_m,y_m` rows) and its firmware's telemetry decimation
//! (`[telemetry] every_ticks`, default 10: the flashed Black Pill's, and
//! `firmware-sim hil`'s default of `--telemetry-every`). Every key means
//! what the scenario key of the same name means, and the same code checks
//! it.
//!
//! A scenario names its robot (`robot = "robots/example.toml"`, relative to
//! the scenario file) or embeds it (`[robot]` with the same keys). The
//! robot's tables then replace the scenario's: a scenario that also gives
//! one of them (other than at its default) is refused, naming the key. The
//! robot's position source is its reader on its floor.
//!
//! Faults injected into the reader's link are the experiment's, not the
//! robot's: a scenario naming a robot keeps them, written as in a scenario
//! without one, in its `[position]` table with `kind = "reader"` and only
//! the fault keys `corrupt_byte_probability`, `drop_frame_probability` and
//! `seed` (any other `position` key is the robot's: refused, naming it):
//!
//! ```toml
//! robot = "example.toml"
//! [position]
//! kind = "reader"
//! drop_frame_probability = 0.2
//! seed = 7
//! ```
//!
//! A tag-map floor becomes the scenario's `[[floor_tags]]` rows (the
//! resolved scenario is self-contained): the simulated reader reads the
//! map's tag nearest to the antenna (within `read_radius_m` in `range`
//! mode, the grid's rule) and reports its id; the robot resolves it
//! through the core's `TagMap` (`crate::tags::MapFloor`), counting ids it
//! does not know (`rfid.unknown_tags`). `firmware-sim hil` runs it too:
//! the HIL link announces the map in `Configure` and sends it in chunks
//! (`crate::simulation::hil_map_chunks`), which the firmware loads into
//! the core's `TagMap` (up to `wmr_link::MAP_CAPACITY` tags, at least
//! [`MAX_MAPPED_TAGS`]).

use std::path::Path;

use wmr_core::devices::TagId;
use wmr_core::devices::tag_grid::TagGridSpec;
use wmr_core::estimation::spec::EstimatorSpec;
use wmr_core::pilot::spec::PilotSpec;
use wmr_core::reference::TrajectorySpec;
use wmr_core::reference::route::Waypoint;

use super::route::ReferenceSpec;
use wmr_link::image;

use super::defaults;
use super::error::ScenarioError;
pub use super::robot_file::{FloorSpec, MappedTag, ReaderSpec, RobotFile, RobotSource};
use super::schema::{GivenKeys, Scenario};
use super::tables::{
    ControllerSpec, FailsafeSpec, FloorTagSpec, ObserverSpec, PlantSpec, PositionSpec,
};

/// The faults a scenario injects into its robot's reader link (the
/// scenario's `position.corrupt_byte_probability`,
/// `position.drop_frame_probability` and `position.seed`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReaderFaults {
    /// Probability that a byte arrives with a flipped bit.
    pub corrupt_byte_probability: f64,
    /// Probability that a frame is lost.
    pub drop_frame_probability: f64,
    /// Seed of the fault RNG.
    pub seed: u64,
}

impl Default for ReaderFaults {
    /// None (the seed at its default).
    fn default() -> Self {
        Self {
            corrupt_byte_probability: 0.0,
            drop_frame_probability: 0.0,
            seed: defaults::seed(),
        }
    }
}

impl ReaderFaults {
    /// The fault keys of a scenario's `position` table; the error names
    /// the first other key given (other than at its default), which is the
    /// robot's. `Exact` (no `[position]` table) is no fault.
    fn of_scenario(position: &PositionSpec, robot: &str) -> Result<Self, ScenarioError> {
        let PositionSpec::Reader {
            corrupt_byte_probability,
            drop_frame_probability,
            seed,
            ..
        } = *position
        else {
            return match position {
                PositionSpec::Exact => Ok(Self::default()),
                _ => Err(ScenarioError::invalid(
                    "position.kind",
                    format!(
                        "the scenario's robot ({robot}) reads its own floor: a scenario naming \
                         a robot gives only kind = \"reader\" and the reader's fault keys"
                    ),
                )),
            };
        };
        let faults = Self {
            corrupt_byte_probability,
            drop_frame_probability,
            seed,
        };
        let mut rest = *position;
        Self::default().write_into(&mut rest);
        let reader = PositionSpec::reader_defaults();
        if rest != reader {
            // Name the first key that differs (both are plain tables).
            let table = |p: &PositionSpec| toml::Table::try_from(p).unwrap_or_default();
            let (given, default) = (table(&rest), table(&reader));
            let key = given
                .iter()
                .find(|(k, v)| default.get(*k) != Some(*v))
                .or_else(|| default.iter().find(|(k, _)| !given.contains_key(*k)))
                .map_or_else(|| "position".to_owned(), |(k, _)| format!("position.{k}"));
            return Err(ScenarioError::invalid(
                &key,
                format!(
                    "the scenario's robot ({robot}) sets it: remove it from the scenario (a \
                     scenario naming a robot keeps only the reader's fault keys \
                     corrupt_byte_probability, drop_frame_probability and seed)"
                ),
            ));
        }
        Ok(faults)
    }

    /// Writes these faults into `position`'s fault keys (a reader's;
    /// nothing otherwise).
    fn write_into(self, position: &mut PositionSpec) {
        if let PositionSpec::Reader {
            corrupt_byte_probability,
            drop_frame_probability,
            seed,
            ..
        } = position
        {
            *corrupt_byte_probability = self.corrupt_byte_probability;
            *drop_frame_probability = self.drop_frame_probability;
            *seed = self.seed;
        }
    }
}

/// A robot file as loaded: its tables and, for a tag-map floor, the map.
#[derive(Debug, Clone, PartialEq)]
pub struct Robot {
    /// The file's tables.
    pub file: RobotFile,
    /// Where it came from (named in errors).
    pub path: String,
    /// The tag map, sorted by id (empty for a grid floor).
    pub tags: Vec<MappedTag>,
    /// The keys the file gave (warnings name a key that does not apply
    /// only where the file wrote it).
    pub given: GivenKeys,
}

/// Most tags a tag map may hold (the flash image's table; 16 bytes each).
pub const MAX_MAPPED_TAGS: usize = 4096;

fn robot_error(path: &str, field: &str, reason: impl Into<String>) -> ScenarioError {
    ScenarioError::Robot {
        path: path.to_owned(),
        field: field.to_owned(),
        reason: reason.into(),
    }
}

/// Parses a tag map CSV (`id,x_m,y_m`; `#` comments, blank lines and one
/// header row allowed), sorted by id.
///
/// # Errors
/// [`ScenarioError::Robot`] naming the file, line and reason: a malformed
/// row, an id wider than 40 bits, a duplicate id, a non-finite position,
/// more than [`MAX_MAPPED_TAGS`] tags or none.
pub fn parse_tag_map(path: &str, text: &str) -> Result<Vec<MappedTag>, ScenarioError> {
    let mut tags = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let at = format!("line {}", n + 1);
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let [id, x, y] = cells.as_slice() else {
            return Err(robot_error(
                path,
                &at,
                format!("expected 3 cells `id,x_m,y_m`, got {}", cells.len()),
            ));
        };
        if tags.is_empty() && id.eq_ignore_ascii_case("id") {
            continue; // the header row
        }
        let id = match id.strip_prefix("0x").or_else(|| id.strip_prefix("0X")) {
            Some(hex) => u64::from_str_radix(hex, 16),
            None => id.parse::<u64>(),
        }
        .map_err(|e| robot_error(path, &at, format!("id `{id}`: {e}")))?;
        if id > TagId::MASK {
            return Err(robot_error(
                path,
                &at,
                format!("id {id:#x} is wider than the reader's 40 bits"),
            ));
        }
        let coordinate = |name: &str, v: &str| -> Result<f64, ScenarioError> {
            v.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && (*v as f32).is_finite())
                .ok_or_else(|| {
                    robot_error(path, &at, format!("{name} `{v}` is not a finite number"))
                })
        };
        tags.push(MappedTag {
            id: TagId(id),
            x_m: coordinate("x_m", x)?,
            y_m: coordinate("y_m", y)?,
        });
    }
    if tags.is_empty() {
        return Err(robot_error(path, "floor.file", "the tag map has no tags"));
    }
    if tags.len() > MAX_MAPPED_TAGS {
        return Err(robot_error(
            path,
            "floor.file",
            format!(
                "{} tags: at most {MAX_MAPPED_TAGS} fit the firmware's table",
                tags.len()
            ),
        ));
    }
    tags.sort_by_key(|t| t.id.0);
    if let Some(w) = tags.windows(2).find(|w| w[0].id == w[1].id) {
        return Err(robot_error(
            path,
            "floor.file",
            format!("tag id {:#x} appears twice", w[0].id.0),
        ));
    }
    Ok(tags)
}

impl Robot {
    /// Reads and parses a robot file (and its tag map), paths relative to
    /// the file.
    ///
    /// # Errors
    /// [`ScenarioError::Io`], [`ScenarioError::Parse`] naming the file, or
    /// [`ScenarioError::Robot`] for the tag map.
    pub fn from_file(path: &Path) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| ScenarioError::io("robot file", path, source))?;
        let parse_error = |e: toml::de::Error| {
            ScenarioError::Parse(format!("robot file {}: {e}", path.display()))
        };
        let file: RobotFile = toml::from_str(&text).map_err(parse_error)?;
        let given = GivenKeys::of_toml(&text).map_err(parse_error)?;
        Self::new(file, path.display().to_string(), path.parent()).map(|r| r.given(given))
    }

    /// This robot, its file having given `keys`.
    #[must_use]
    pub fn given(mut self, keys: GivenKeys) -> Self {
        self.given = keys;
        self
    }

    /// The keys the robot file gave where they do not apply to its setup
    /// (ignored, so probably a mistake): one line each, naming the file,
    /// the key and why, in the robot file's own names.
    #[must_use]
    pub fn warnings(&self) -> Vec<String> {
        // Which keys apply does not depend on the reference.
        let reference = self
            .file
            .reference
            .clone()
            .unwrap_or(ReferenceSpec::Trajectory(TrajectorySpec::FigureEight {
                h1_m: TrajectorySpec::PAPER_H1_M,
                h2_rad_s: TrajectorySpec::PAPER_H2_RAD_S,
                phase_rad: TrajectorySpec::PAPER_PHASE_RAD,
            }));
        let mut scenario = self.scenario(reference, 1.0);
        scenario.given = GivenKeys::default().with_robot(self.path.clone(), self.given.clone());
        scenario.warnings()
    }

    /// A robot from its parsed tables; `dir` is where a tag map's path is
    /// taken from (`None`: no file is read, and a tag map is refused).
    ///
    /// # Errors
    /// The tag map cannot be read or is refused.
    pub fn new(
        mut file: RobotFile,
        path: String,
        dir: Option<&Path>,
    ) -> Result<Self, ScenarioError> {
        // A route's CSV is read now (relative to the robot file) and the
        // route checked at the robot's period, naming the robot file's keys.
        if let Some(ReferenceSpec::Route(route)) = &mut file.reference {
            let in_robot = |e: ScenarioError| match e {
                ScenarioError::Invalid { field, reason } => robot_error(&path, &field, reason),
                other => other,
            };
            route.load_waypoints(dir).map_err(in_robot)?;
            route.validate(file.period_s).map_err(in_robot)?;
        }
        let tags = match &file.floor {
            FloorSpec::Grid { .. } => Vec::new(),
            FloorSpec::TagMap { file: csv } => {
                let Some(dir) = dir else {
                    return Err(robot_error(
                        &path,
                        "floor.file",
                        "a tag map is read relative to its robot file: load the scenario \
                         or robot from a file",
                    ));
                };
                let csv_path = dir.join(csv);
                let text = std::fs::read_to_string(&csv_path).map_err(|source| {
                    ScenarioError::io("tag map", &csv_path, source)
                        .named_by(format!("`floor.file` in robot file {path}"))
                })?;
                parse_tag_map(&csv_path.display().to_string(), &text)?
            }
        };
        Ok(Self {
            file,
            path,
            tags,
            given: GivenKeys::default(),
        })
    }

    /// A scenario tracking `reference` with this robot, from the start of
    /// the reference, for `duration_s` (what the flash image is validated
    /// as).
    #[must_use]
    pub fn scenario(&self, reference: ReferenceSpec, duration_s: f64) -> Scenario {
        let mut scenario = Scenario {
            name: self.file.name.clone(),
            description: self.file.description.clone(),
            duration_s,
            period_s: defaults::period_s(),
            transient_s: 0.0,
            reference,
            initial: super::InitialSpec::default(),
            controller: ControllerSpec::default(),
            observer: ObserverSpec::default(),
            estimator: EstimatorSpec::default(),
            plant: PlantSpec::default(),
            drive: None,
            position: PositionSpec::default(),
            floor_tags: Vec::new(),
            failsafe: FailsafeSpec::default(),
            telemetry: None,
            mavlink: None,
            measurement: super::MeasurementSpec::default(),
            sweep: None,
            robot: None,
            given: GivenKeys::default(),
        };
        self.fill(&mut scenario, ReaderFaults::default());
        scenario
    }

    /// Puts the robot's tables into `scenario`, its reader with `faults`.
    fn fill(&self, scenario: &mut Scenario, faults: ReaderFaults) {
        let r = &self.file;
        scenario.period_s = r.period_s;
        scenario.plant = r.plant;
        scenario.drive = Some(r.drive);
        scenario.controller = r.controller;
        scenario.observer = r.observer;
        scenario.estimator = r.estimator;
        scenario.failsafe = r.failsafe;
        scenario.telemetry = Some(r.telemetry);
        scenario.mavlink = r.mavlink;
        let (spacing_m, offset_m, margin_m, extent_m) = match r.floor {
            FloorSpec::Grid {
                spacing_m,
                offset_m,
                margin_m,
                extent_m,
            } => (spacing_m, offset_m, margin_m, extent_m),
            // Not a grid: `floor_tags` is the floor (the grid keys unused).
            FloorSpec::TagMap { .. } => (0.0, [0.0; 2], 0.0, None),
        };
        scenario.floor_tags = self
            .tags
            .iter()
            .map(|t| FloorTagSpec {
                id: t.id.0,
                x_m: t.x_m,
                y_m: t.y_m,
            })
            .collect();
        let reader = r.reader;
        scenario.position = PositionSpec::Reader {
            spacing_m,
            offset_m,
            margin_m,
            extent_m,
            mode: reader.mode,
            read_radius_m: reader.read_radius_m,
            antenna_offset_m: reader.antenna_offset_m,
            antenna_offset_compensated: true,
            baud: reader.baud,
            repeat_interval_s: reader.repeat_interval_s,
            corrupt_byte_probability: faults.corrupt_byte_probability,
            drop_frame_probability: faults.drop_frame_probability,
            seed: faults.seed,
        };
    }

    /// The robot file's key a scenario key of a filled-in scenario came
    /// from (`position.spacing_m` → `floor.spacing_m`).
    pub(crate) fn key_of(field: &str) -> Option<String> {
        let (head, rest) = field.split_once('.').unwrap_or((field, ""));
        let robot_key = match head {
            "period_s" | "plant" | "drive" | "controller" | "observer" | "estimator"
            | "failsafe" | "telemetry" | "mavlink" => return Some(field.to_owned()),
            "position" => match rest {
                "spacing_m" | "offset_m" | "margin_m" | "extent_m" => format!("floor.{rest}"),
                "" => "reader".to_owned(),
                _ => format!("reader.{rest}"),
            },
            _ => return None,
        };
        Some(robot_key)
    }

    /// `e` with the robot file named, when it is about one of its keys.
    #[must_use]
    pub fn name_in(&self, e: ScenarioError) -> ScenarioError {
        match e {
            ScenarioError::Invalid { field, reason } => match Self::key_of(&field) {
                Some(key) => robot_error(&self.path, &key, reason),
                None => ScenarioError::Invalid { field, reason },
            },
            other => other,
        }
    }
}

/// The scenario's top-level keys a robot file sets: a scenario that names
/// a robot may give none of them, even at its default value (`position` is
/// the robot's too, but for the reader's fault keys: [`ReaderFaults`]).
pub const ROBOT_KEYS: [&str; 10] = [
    "mavlink",
    "period_s",
    "plant",
    "drive",
    "controller",
    "observer",
    "estimator",
    "failsafe",
    "telemetry",
    "floor_tags",
];

impl Scenario {
    /// Replaces `self.robot` by its tables (read from the file it names,
    /// relative to `dir`; with `None` no file is read: a robot file or tag
    /// map is refused), and returns the
    /// robot (to name its file in validation errors: [`Robot::name_in`]).
    /// `given` says whether the scenario file gives a top-level key.
    ///
    /// # Errors
    /// The robot file cannot be read or parsed, or a robot table also
    /// given in the scenario ([`ROBOT_KEYS`]).
    pub fn resolve_robot(
        &mut self,
        dir: Option<&Path>,
        given: impl Fn(&str) -> bool,
    ) -> Result<Option<Robot>, ScenarioError> {
        let Some(source) = self.robot.take() else {
            return Ok(None);
        };
        let robot = match source {
            RobotSource::File(name) => {
                let Some(dir) = dir else {
                    return Err(ScenarioError::invalid(
                        "robot",
                        format!(
                            "`{name}` is relative to the scenario file: load the scenario from \
                             its file (or embed the robot as [robot])"
                        ),
                    ));
                };
                Robot::from_file(&dir.join(&name))
                    .map_err(|e| e.named_by(format!("the scenario's `robot = \"{name}\"`")))?
            }
            RobotSource::Inline(file) => {
                Robot::new(*file, "[robot]".to_owned(), dir)?.given(self.given.under("robot"))
            }
        };
        if !matches!(robot.file.plant, PlantSpec::DiffDrive { .. }) {
            return Err(robot_error(
                &robot.path,
                "plant.kind",
                "a robot is a \"diff_drive\" (wheels, encoders, motors)",
            ));
        }
        if let Some(key) = ROBOT_KEYS.iter().find(|key| given(key)) {
            return Err(ScenarioError::invalid(
                key,
                format!(
                    "the scenario's robot ({}) sets it: remove it from the scenario",
                    robot.path
                ),
            ));
        }
        let faults = ReaderFaults::of_scenario(&self.position, &robot.path)?;
        robot.fill(self, faults);
        self.given =
            std::mem::take(&mut self.given).with_robot(robot.path.clone(), robot.given.clone());
        Ok(Some(robot))
    }
}

/// The Black Pill's watchdog timeout, ms (`firmware/src/board/blackpill.rs`
/// `WATCHDOG_MS`).
pub const BLACKPILL_WATCHDOG_MS: u32 = 50;

/// How far along the reference the flash image's automatic tag grid
/// reaches (without `floor.extent_m`), s: an hour of it.
pub const FLASH_GRID_REFERENCE_S: f64 = 3600.0;

/// The floor of a flash image.
#[derive(Debug, Clone, PartialEq)]
pub enum FlashFloor {
    /// A tag grid.
    Grid(TagGridSpec),
    /// A tag map, sorted by id.
    Map(Vec<(TagId, [f32; 2])>),
}

/// A robot's flash image (`cargo xtask firmware --robot FILE`).
#[derive(Debug, Clone, PartialEq)]
pub struct FlashImage {
    /// The pilot, validated by the core's constructors.
    pub pilot: PilotSpec,
    /// The floor.
    pub floor: FlashFloor,
    /// A telemetry record every this many ticks (`telemetry.every_ticks`).
    pub telemetry_every_ticks: u16,
    /// The route the robot follows instead of its pilot's trajectory
    /// (`reference.kind = "route"`): as the image announces it, and its
    /// waypoints. The core checked it as the board will
    /// (`RoutePlan::new`).
    pub route: Option<(wmr_link::RouteSpec, Vec<Waypoint>)>,
    /// The encoded image ([`wmr_link::image`]).
    pub bytes: Vec<u8>,
}

impl Robot {
    /// The robot's flash image: its pilot exactly as every simulation of
    /// it builds it (the same validation, down to the core's
    /// constructors), tracking its `[reference]` (a route rides in the
    /// image, checked by the core's planner as the board checks it), and
    /// its floor: the tag map, or the grid covering
    /// [`FLASH_GRID_REFERENCE_S`] of the reference (or `floor.extent_m`).
    ///
    /// # Errors
    /// [`ScenarioError::Robot`] naming the robot file's key: no
    /// `[reference]`, a value the simulator or the core refuses, a tag map
    /// with the fusion estimator and a nearest-tag reader (whose cell
    /// measurements need a grid's spacing) or no
    /// `estimator.fusion.max_blind_distance_m`.
    pub fn flash_image(&self) -> Result<FlashImage, ScenarioError> {
        let reference = match &self.file.reference {
            None => {
                return Err(robot_error(
                    &self.path,
                    "reference",
                    "the firmware needs the trajectory it tracks: add a [reference] table",
                ));
            }
            Some(reference) => reference.clone(),
        };
        // A tag map is validated on a stand-in grid, then the estimators
        // are told there is none (tag spacing 0).
        let mut stand_in = self.clone();
        if let FloorSpec::TagMap { .. } = self.file.floor {
            stand_in.file.floor = FloorSpec::Grid {
                spacing_m: defaults::spacing_m(),
                offset_m: [0.0; 2],
                margin_m: defaults::margin_m(),
                extent_m: None,
            };
            stand_in.tags.clear();
        }
        let scenario = stand_in.scenario(reference, FLASH_GRID_REFERENCE_S);
        let setup = scenario.validate().map_err(|e| self.name_in(e))?;
        let route = setup
            .route
            .as_ref()
            .map(|r| (r.spec(), r.waypoints.as_slice().to_vec()));
        let (
            super::PlantSetup::DiffDrive { pilot_spec, .. },
            super::PositionSetup::Reader(floor, _),
        ) = (setup.plant, setup.position)
        else {
            return Err(robot_error(
                &self.path,
                "plant.kind",
                "a robot is a \"diff_drive\" with a reader",
            ));
        };
        let mut pilot = pilot_spec;
        // The Black Pill's check of the image's period (its `image_config`).
        let tick_us = (pilot.tracker.period_s * 1.0e6 + 0.5) as u32;
        if !(1_000..=100_000).contains(&tick_us)
            || BLACKPILL_WATCHDOG_MS * 1_000 * 2 / 3 < tick_us.saturating_mul(3)
        {
            return Err(robot_error(
                &self.path,
                "period_s",
                format!(
                    "the Black Pill runs periods of 1 ms to 100 ms that its \
                     {BLACKPILL_WATCHDOG_MS} ms watchdog outlasts three times over (got {tick_us} µs)"
                ),
            ));
        }
        let floor = if let (true, Some(grid)) = (self.tags.is_empty(), floor.grid()) {
            FlashFloor::Grid(TagGridSpec::of(grid.grid()))
        } else {
            pilot.tracker.sensors.tag_spacing_m = 0.0;
            pilot.build().map_err(|e| {
                robot_error(
                    &self.path,
                    "floor.kind",
                    format!("on a tag map (no grid spacing), refused by the core: {e}"),
                )
            })?;
            FlashFloor::Map(
                self.tags
                    .iter()
                    .map(|t| (t.id, [t.x_m as f32, t.y_m as f32]))
                    .collect(),
            )
        };
        let mut bytes = vec![0; image::max_image_bytes(self.tags.len())];
        let encoded = match &floor {
            FlashFloor::Grid(grid) => image::ImageFloorSpec::Grid(*grid),
            FlashFloor::Map(tags) => image::ImageFloorSpec::Map(tags),
        };
        let telemetry_every_ticks = self
            .file
            .telemetry
            .every_ticks()
            .map_err(|e| self.name_in(e))?;
        let len = image::encode(
            &pilot,
            telemetry_every_ticks,
            route.as_ref().map(|(spec, w)| (spec, w.as_slice())),
            &encoded,
            &mut bytes,
        )
        .map_err(|e| robot_error(&self.path, "floor", e.to_string()))?;
        bytes.truncate(len);
        Ok(FlashImage {
            pilot,
            floor,
            telemetry_every_ticks,
            route,
            bytes,
        })
    }
}
