//! `[reference] kind = "route"`: a route through waypoints (the core's
//! [`wmr_core::reference::route`]) in a scenario or robot file, its keys,
//! its waypoints (inline or from a CSV file) and its checks.
//!
//! # Keys and units
//!
//! Every key carries its unit in its name, as in the rest of the file.
//! The route's angles are in **degrees** (`heading_deg`,
//! `pivot_threshold_deg`, `pivot_rate_deg_s`, `pivot_accel_deg_s2`,
//! `heading_tolerance_deg`): stations and tolerances are surveyed and
//! specified in degrees (the product goal is 1°); the core gets radians.
//! Headings are counter-clockwise from the floor's +x axis, as
//! `initial.heading_rad`.
//!
//! # Waypoints
//!
//! Either inline, an array of tables:
//!
//! ```toml
//! [[reference.waypoints]]
//! x_m = 0.0
//! y_m = 0.0
//! stop_s = 2.0        # optional: a stop of 2 s (absent: driven through)
//! heading_deg = 90.0  # optional: face +y while stopped (a stop, of 0 s if no stop_s)
//! speed_m_s = 0.3     # optional: speed limit of the leg that ends here
//! ```
//!
//! or `waypoints_csv = "FILE"`, relative to the file that names it, whose
//! first row (after `#` comments and blank lines) is a header naming the
//! columns `x_m,y_m,stop_s,heading_deg,speed_m_s` (`x_m`, `y_m` required,
//! the others optional, in any order) and whose empty cells are absent
//! values. Giving both is refused. A file's CSV is read when the file is
//! loaded and becomes inline waypoints: the resolved scenario (a sweep
//! run's `scenario.toml`) is self-contained.
//!
//! The first and last waypoints are always stops (the core's rule: a route
//! starts and ends at rest).
//!
//! # Refusals
//!
//! A waypoint is named **1-based**, in file order: `reference.waypoints[3].heading_deg`
//! is the third `[[reference.waypoints]]` table's key; for a CSV,
//! `reference.waypoints_csv` with the file, its line and the waypoint's
//! number. The core's [`RouteError`] (which counts from 0) is mapped to
//! the waypoint and the key that caused it, with the value.

use std::path::Path;

use serde::{Deserialize, Serialize};
use wmr_core::pilot::route::{RouteOptions, RouteOptionsSpec, RouteStart};
use wmr_core::reference::TrajectorySpec;
use wmr_core::reference::route::{
    LimitKey, RouteError, RouteLimits, RouteLimitsSpec, RoutePlan, Waypoint, WaypointKey, Waypoints,
};

use super::error::{ScenarioError, in_range, non_negative, shown};

/// The `[reference]` table: one of the core's analytic references
/// ([`TrajectorySpec`]: `figure_eight`, `circle`, `line`) or a route
/// (`kind = "route"`, [`RouteSpec`]).
#[derive(Debug, Clone, PartialEq)]
pub enum ReferenceSpec {
    /// An analytic reference of the core.
    Trajectory(TrajectorySpec),
    /// A route through waypoints.
    Route(Box<RouteSpec>),
}

impl From<TrajectorySpec> for ReferenceSpec {
    fn from(t: TrajectorySpec) -> Self {
        Self::Trajectory(t)
    }
}

/// The reference kinds a file may name.
const KINDS: &str = "`figure_eight`, `circle`, `line`, `route`";

/// The route as a table tagged `kind = "route"` (serde's internal tag).
#[derive(Serialize, Deserialize, schemars::JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case")]
enum TaggedRoute {
    /// A route through waypoints (the core's `wmr_core::reference::route`):
    /// straight legs, clothoid corner blends, stops, pivots in place and a
    /// speed profile under the limits below.
    Route(RouteSpec),
}

/// [`TaggedRoute`] borrowed, to serialize.
#[derive(Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
enum TaggedRouteRef<'a> {
    Route(&'a RouteSpec),
}

impl Serialize for ReferenceSpec {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Self::Trajectory(t) => t.serialize(s),
            Self::Route(r) => TaggedRouteRef::Route(r).serialize(s),
        }
    }
}

impl<'de> Deserialize<'de> for ReferenceSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error as _;
        let table = toml::Table::deserialize(d)?;
        match table.get("kind").and_then(toml::Value::as_str) {
            Some("route") => TaggedRoute::deserialize(toml::Value::Table(table))
                .map(|TaggedRoute::Route(r)| Self::Route(Box::new(r)))
                .map_err(|e| D::Error::custom(format!("[reference] (kind = \"route\"): {e}"))),
            Some("figure_eight" | "circle" | "line") => {
                TrajectorySpec::deserialize(toml::Value::Table(table))
                    .map(Self::Trajectory)
                    .map_err(|e| D::Error::custom(format!("[reference]: {e}")))
            }
            Some(other) => Err(D::Error::custom(format!(
                "[reference]: unknown kind `{other}`, expected one of {KINDS}"
            ))),
            None => Err(D::Error::custom(format!(
                "[reference]: missing field `kind` (one of {KINDS})"
            ))),
        }
    }
}

impl schemars::JsonSchema for ReferenceSpec {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "ReferenceSpec".into()
    }

    /// One `oneOf` of every kind's table, each tagged by its `kind`: the
    /// core's analytic references and the route.
    fn json_schema(generator: &mut schemars::SchemaGenerator) -> schemars::Schema {
        let variants = |schema: schemars::Schema| -> Vec<serde_json::Value> {
            let value = schema.to_value();
            match value.get("oneOf").and_then(serde_json::Value::as_array) {
                Some(items) => items.clone(),
                None => vec![value],
            }
        };
        let mut all = variants(TrajectorySpec::json_schema(generator));
        all.extend(variants(TaggedRoute::json_schema(generator)));
        schemars::json_schema!({
            "description": "The reference: `kind` chooses an analytic trajectory of the core or a route through waypoints.",
            "oneOf": all,
        })
    }
}

/// How the route's first leg starts (the core's [`RouteStart`]).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum RouteStartSpec {
    /// At the first waypoint, as given: the law joins the route from
    /// wherever the robot is.
    #[default]
    AsGiven,
    /// At the robot's first fix: the first waypoint's position (and its
    /// heading to face) is replaced by the estimate when the route starts.
    FromFirstFix,
    /// As `as_given`, and the robot is known to face the first leg (or
    /// the first waypoint's `heading_deg`) there: the estimator takes that
    /// heading when the route starts (a robot parked at its station).
    AsGivenHeadingKnown,
}

impl From<RouteStartSpec> for RouteStart {
    fn from(s: RouteStartSpec) -> Self {
        match s {
            RouteStartSpec::AsGiven => Self::AsGiven,
            RouteStartSpec::FromFirstFix => Self::FromFirstFix,
            RouteStartSpec::AsGivenHeadingKnown => Self::AsGivenHeadingKnown,
        }
    }
}

/// One waypoint (`[[reference.waypoints]]`, or a CSV row).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct WaypointSpec {
    /// Position x on the floor, m.
    pub x_m: f64,
    /// Position y on the floor, m.
    pub y_m: f64,
    /// A stop here for this long, s (≥ 0; not given: driven through, a
    /// corner blend, unless `heading_deg` is given). The first and last
    /// waypoints are always stops (0 s when not given).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop_s: Option<f64>,
    /// Heading to face while stopped here, degrees counter-clockwise from
    /// +x (makes the waypoint a stop, of 0 s without `stop_s`; not given:
    /// keep the arrival heading).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heading_deg: Option<f64>,
    /// Speed limit of the leg that ends here, m/s (> 0; not given:
    /// `max_speed_m_s`; not used on the first waypoint).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_m_s: Option<f64>,
}

/// Where the waypoints were read from (not serialized: the resolved file
/// holds them inline), for the refusals to name the CSV's lines. Any two
/// compare equal, as provenance.
#[derive(Debug, Clone, Default)]
pub struct WaypointOrigin {
    csv: Option<(String, Vec<usize>)>,
}

impl PartialEq for WaypointOrigin {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// `[reference]` with `kind = "route"`: the plan's limits, how the route
/// is followed, and its waypoints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RouteSpec {
    /// Largest reference speed, m/s.
    #[serde(default = "RouteSpec::default_max_speed_m_s")]
    #[schemars(range(min = 1e-6, max = 100.0))]
    pub max_speed_m_s: f64,
    /// Largest tangential acceleration and deceleration, m/s².
    #[serde(default = "RouteSpec::default_max_tangential_accel_m_s2")]
    pub max_tangential_accel_m_s2: f64,
    /// Largest lateral acceleration `v² κ` on the corner blends, m/s².
    #[serde(default = "RouteSpec::default_max_lateral_accel_m_s2")]
    pub max_lateral_accel_m_s2: f64,
    /// Distance from a corner waypoint to its clothoid blend (the blend's
    /// largest deviation from the polyline), m.
    #[serde(default = "RouteSpec::default_blend_deviation_m")]
    pub blend_deviation_m: f64,
    /// At a stop, a direction change larger than this is turned in place
    /// (a pivot), degrees in [0, 180].
    #[serde(default = "RouteSpec::default_pivot_threshold_deg")]
    #[schemars(range(min = 0.0, max = 180.0))]
    pub pivot_threshold_deg: f64,
    /// Largest angular rate of a pivot, degrees per second.
    #[serde(default = "RouteSpec::default_pivot_rate_deg_s")]
    pub pivot_rate_deg_s: f64,
    /// Largest angular acceleration of a pivot, degrees per second squared.
    #[serde(default = "RouteSpec::default_pivot_accel_deg_s2")]
    pub pivot_accel_deg_s2: f64,
    /// The pivot's heading gain `k_θ`, 1/s, in (0, 1000].
    #[serde(default = "RouteSpec::default_pivot_gain_per_s")]
    pub pivot_gain_per_s: f64,
    /// A stop whose estimated position error at a settle exceeds this is
    /// counted (`route.counters.stop_errors`), m.
    #[serde(default = "RouteSpec::default_position_tolerance_m")]
    pub position_tolerance_m: f64,
    /// A stop whose estimated heading error at a settle exceeds this is
    /// counted, degrees.
    #[serde(default = "RouteSpec::default_heading_tolerance_deg")]
    pub heading_tolerance_deg: f64,
    /// The route's clock waits while the robot lags the moving reference
    /// by more than this along the path, m (> 0).
    #[serde(default = "RouteSpec::default_max_lag_m")]
    pub max_lag_m: f64,
    /// Largest speed of the approach onto a stop reached short or long,
    /// m/s, in (0, 1].
    #[serde(default = "RouteSpec::default_approach_speed_m_s")]
    #[schemars(range(min = 1e-6, max = 1.0))]
    pub approach_speed_m_s: f64,
    /// Longest approach onto a stop before it is taken as reached where
    /// the robot is (counted), s (≥ 0; 0: no approach).
    #[serde(default = "RouteSpec::default_approach_timeout_s")]
    #[schemars(range(min = 0.0))]
    pub approach_timeout_s: f64,
    /// Where the first leg starts.
    #[serde(default)]
    pub start: RouteStartSpec,
    /// The run ends this long after the route is done (the robot settled
    /// on the last waypoint), or at `duration_s`, whichever comes first, s.
    #[serde(default = "RouteSpec::default_settle_s")]
    pub settle_s: f64,
    /// The waypoints, in order (at least 2, at most 64); or give
    /// `waypoints_csv`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub waypoints: Vec<WaypointSpec>,
    /// A CSV file of the waypoints (header `x_m,y_m,stop_s,heading_deg,speed_m_s`,
    /// empty cells absent), relative to the file that names it; read when
    /// the file is loaded. Not with `[[reference.waypoints]]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub waypoints_csv: Option<String>,
    /// Where the waypoints came from.
    #[serde(skip)]
    #[schemars(skip)]
    pub origin: WaypointOrigin,
}

/// The route, validated: what a run loads into its
/// [`wmr_core::pilot::route::RouteFollower`], and its plan as given.
#[derive(Debug, Clone, PartialEq)]
pub struct RouteSetup {
    /// The waypoints.
    pub waypoints: Waypoints,
    /// The plan's limits.
    pub limits: RouteLimits,
    /// The limits as numbers (what the HIL link and the flash image carry).
    pub limits_spec: RouteLimitsSpec,
    /// How it is followed (pivot gain, stop tolerances).
    pub options: RouteOptions,
    /// Where the first leg starts.
    pub start: RouteStart,
    /// Time the run goes on after the route is done, s.
    pub settle_s: f64,
    /// The route run's MAVLink endpoint and power-on (the scenario's or
    /// robot file's `[mavlink]`, checked).
    pub mavlink: wmr_link::MavlinkSettings,
    /// The plan of the waypoints as given (with `from_first_fix` the run's
    /// own plan starts at the first fix instead).
    pub plan: Box<RoutePlan>,
}

impl RouteSetup {
    /// The route as the link announces it and the flash image holds it
    /// (its waypoints go separately).
    #[must_use]
    pub fn spec(&self) -> wmr_link::RouteSpec {
        wmr_link::RouteSpec {
            // At most `ROUTE_CAPACITY` waypoints: fits (the link's tests).
            waypoints: u8::try_from(self.waypoints.as_slice().len()).unwrap_or(u8::MAX),
            limits: self.limits_spec,
            options: self.options.spec(),
            start: self.start,
            mavlink: self.mavlink,
        }
    }

    /// The analytic stand-in the tracker's configuration holds (a
    /// [`TrajectorySpec`] is part of it): a line from the first waypoint
    /// along the first leg at `max_speed_m_s`. A route run never samples
    /// it (`step_route` samples the route); a sweep takes its start point
    /// (the first waypoint) as the reference's start.
    #[must_use]
    pub fn stand_in(&self) -> TrajectorySpec {
        let w = self.waypoints.as_slice();
        let (p0, p1) = match (w.first(), w.get(1)) {
            (Some(a), Some(b)) => (a.position_m, b.position_m),
            _ => Default::default(),
        };
        TrajectorySpec::Line {
            start_m: [p0.x, p0.y],
            heading_rad: (p1.y - p0.y).atan2(p1.x - p0.x),
            speed_m_s: self.limits.max_speed_m_s(),
        }
    }

    /// The waypoints that are stops, `(index from 0, waypoint)`.
    pub fn stops(&self) -> impl Iterator<Item = (usize, &Waypoint)> {
        let n = self.waypoints.len();
        self.waypoints
            .as_slice()
            .iter()
            .enumerate()
            .filter(move |(i, w)| w.stop.is_some() || *i == 0 || *i + 1 == n)
    }
}

impl RouteSpec {
    /// Default `max_speed_m_s`, m/s.
    pub const DEFAULT_MAX_SPEED_M_S: f64 = 0.3;
    fn default_max_speed_m_s() -> f64 {
        Self::DEFAULT_MAX_SPEED_M_S
    }
    fn default_max_tangential_accel_m_s2() -> f64 {
        0.5
    }
    fn default_max_lateral_accel_m_s2() -> f64 {
        0.5
    }
    fn default_blend_deviation_m() -> f64 {
        0.05
    }
    fn default_pivot_threshold_deg() -> f64 {
        30.0
    }
    fn default_pivot_rate_deg_s() -> f64 {
        60.0
    }
    fn default_pivot_accel_deg_s2() -> f64 {
        120.0
    }
    fn default_pivot_gain_per_s() -> f64 {
        f64::from(RouteOptions::DEFAULT_PIVOT_GAIN_PER_S)
    }
    /// The core's default (`RouteOptions::DEFAULT_POSITION_TOLERANCE_M`),
    /// as a file writes it.
    fn default_position_tolerance_m() -> f64 {
        0.01
    }
    fn default_heading_tolerance_deg() -> f64 {
        1.0
    }
    /// The core's defaults (`RouteOptions::DEFAULT_MAX_LAG_M`,
    /// `DEFAULT_APPROACH_SPEED_M_S`, `DEFAULT_APPROACH_TIMEOUT_S`), as a
    /// file writes them (a test holds them equal).
    fn default_max_lag_m() -> f64 {
        0.05
    }
    fn default_approach_speed_m_s() -> f64 {
        0.05
    }
    fn default_approach_timeout_s() -> f64 {
        5.0
    }
    fn default_settle_s() -> f64 {
        2.0
    }

    /// Reads `waypoints_csv`, relative to `dir`, into `waypoints` (the
    /// file is then self-contained); `file_key` names the key in errors
    /// (`reference.waypoints_csv`).
    ///
    /// # Errors
    /// Both inline waypoints and a CSV; a CSV without a directory to read
    /// it from (a text not loaded from a file); the file cannot be read;
    /// a malformed CSV (named by file, line and column).
    pub fn load_waypoints(&mut self, dir: Option<&Path>) -> Result<(), ScenarioError> {
        const KEY: &str = "reference.waypoints_csv";
        let Some(csv) = self.waypoints_csv.clone() else {
            return Ok(());
        };
        if !self.waypoints.is_empty() {
            return Err(ScenarioError::invalid(
                KEY,
                format!(
                    "both [[reference.waypoints]] ({} given) and waypoints_csv = \"{csv}\" are \
                     given: give one",
                    self.waypoints.len()
                ),
            ));
        }
        let Some(dir) = dir else {
            return Err(ScenarioError::invalid(
                KEY,
                format!(
                    "\"{csv}\" is read relative to its file: load the file from disk, or give \
                     the waypoints inline"
                ),
            ));
        };
        let path = dir.join(&csv);
        let text = std::fs::read_to_string(&path).map_err(|source| {
            ScenarioError::io("waypoint file", &path, source).named_by(format!("`{KEY}`"))
        })?;
        let shown_path = path.display().to_string();
        let (waypoints, lines) = parse_waypoints_csv(&shown_path, &text)?;
        self.waypoints = waypoints;
        self.waypoints_csv = None;
        self.origin.csv = Some((shown_path, lines));
        Ok(())
    }

    /// The field a refusal of waypoint `index` (from 0) names, and the
    /// prefix of its reason (`FILE line L (waypoint N): ` for a CSV).
    fn waypoint_field(&self, index: usize, key: &str) -> (String, String) {
        match &self.origin.csv {
            Some((path, lines)) => (
                "reference.waypoints_csv".into(),
                format!(
                    "{path} line {} (waypoint {}): `{key}` ",
                    lines.get(index).copied().unwrap_or(0),
                    index + 1
                ),
            ),
            None => (
                format!("reference.waypoints[{}].{key}", index + 1),
                String::new(),
            ),
        }
    }

    fn waypoint_error(&self, index: usize, key: &str, reason: String) -> ScenarioError {
        let (field, prefix) = self.waypoint_field(index, key);
        ScenarioError::invalid(&field, format!("{prefix}{reason}"))
    }

    /// The core's waypoints, from degrees to radians.
    fn core_waypoints(&self) -> Vec<Waypoint> {
        self.waypoints
            .iter()
            .map(|w| {
                let mut p = Waypoint::pass(w.x_m as f32, w.y_m as f32);
                if let Some(dwell) = w.stop_s {
                    p = Waypoint::stop(w.x_m as f32, w.y_m as f32, dwell as f32);
                }
                if let Some(h) = w.heading_deg {
                    p = p.facing(h.to_radians() as f32);
                }
                if let Some(v) = w.speed_m_s {
                    p = p.with_speed_limit(v as f32);
                }
                p
            })
            .collect()
    }

    /// The limits as the core takes them (degrees to radians).
    fn limits_spec(&self) -> RouteLimitsSpec {
        RouteLimitsSpec {
            max_speed_m_s: self.max_speed_m_s as f32,
            max_tangential_accel_m_s2: self.max_tangential_accel_m_s2 as f32,
            max_lateral_accel_m_s2: self.max_lateral_accel_m_s2 as f32,
            blend_deviation_m: self.blend_deviation_m as f32,
            pivot_threshold_rad: self.pivot_threshold_deg.to_radians() as f32,
            pivot_rate_rad_s: self.pivot_rate_deg_s.to_radians() as f32,
            pivot_accel_rad_s2: self.pivot_accel_deg_s2.to_radians() as f32,
        }
    }

    /// The file's key of a core limit, and its value as the file wrote it.
    fn limit_key(&self, key: LimitKey) -> (&'static str, f64) {
        match key {
            LimitKey::MaxSpeed => ("max_speed_m_s", self.max_speed_m_s),
            LimitKey::MaxTangentialAccel => {
                ("max_tangential_accel_m_s2", self.max_tangential_accel_m_s2)
            }
            LimitKey::MaxLateralAccel => ("max_lateral_accel_m_s2", self.max_lateral_accel_m_s2),
            LimitKey::BlendDeviation => ("blend_deviation_m", self.blend_deviation_m),
            LimitKey::PivotThreshold => ("pivot_threshold_deg", self.pivot_threshold_deg),
            LimitKey::PivotRate => ("pivot_rate_deg_s", self.pivot_rate_deg_s),
            LimitKey::PivotAccel => ("pivot_accel_deg_s2", self.pivot_accel_deg_s2),
        }
    }

    /// Checks every value and plans the route at `period_s`.
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming the `reference.*` key (a
    /// waypoint's 1-based, or the CSV's line) and its value.
    pub fn validate(&self, period_s: f64) -> Result<RouteSetup, ScenarioError> {
        if let Some(csv) = &self.waypoints_csv {
            // Read at load time; a text parsed without its file cannot.
            return Err(ScenarioError::invalid(
                "reference.waypoints_csv",
                format!("\"{csv}\" was not read: load the file from disk"),
            ));
        }
        // The plausible range of a reference speed (the tracker's stand-in
        // line is built at it, `RouteSetup::stand_in`).
        in_range(
            "reference.max_speed_m_s",
            self.max_speed_m_s,
            wmr_core::plausible::REFERENCE_SPEED_M_S,
            "m/s",
        )?;
        let limits = RouteLimits::new(&self.limits_spec()).map_err(|e| {
            let (key, value) = self.limit_key(e.0);
            let range = match e.0 {
                LimitKey::PivotThreshold => "must be in [0, 180] degrees".to_owned(),
                _ => "must be finite and > 0".to_owned(),
            };
            ScenarioError::invalid(
                &format!("reference.{key}"),
                format!("{range} (got {})", shown(value)),
            )
        })?;
        // Each tolerance and the gain on its own, so the refusal names it.
        let positive = |key: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(v)
            } else {
                Err(ScenarioError::invalid(
                    &format!("reference.{key}"),
                    format!("must be finite and > 0 (got {})", shown(v)),
                ))
            }
        };
        let gain = self.pivot_gain_per_s;
        if !(gain > 0.0 && gain <= 1000.0) {
            return Err(ScenarioError::invalid(
                "reference.pivot_gain_per_s",
                format!("must be in (0, 1000] 1/s (got {})", shown(gain)),
            ));
        }
        let position_tolerance = positive("position_tolerance_m", self.position_tolerance_m)?;
        let heading_tolerance = positive("heading_tolerance_deg", self.heading_tolerance_deg)?;
        let max_lag = positive("max_lag_m", self.max_lag_m)?;
        let approach_speed = self.approach_speed_m_s;
        if !(approach_speed > 0.0 && approach_speed <= 1.0) {
            return Err(ScenarioError::invalid(
                "reference.approach_speed_m_s",
                format!("must be in (0, 1] m/s (got {})", shown(approach_speed)),
            ));
        }
        let approach_timeout =
            non_negative("reference.approach_timeout_s", self.approach_timeout_s)?;
        let options = RouteOptions::new(&RouteOptionsSpec {
            pivot_gain_per_s: gain as f32,
            position_tolerance_m: position_tolerance as f32,
            heading_tolerance_rad: heading_tolerance.to_radians() as f32,
            max_lag_m: max_lag as f32,
            approach_speed_m_s: approach_speed as f32,
            approach_timeout_s: approach_timeout as f32,
        })
        .map_err(|e| {
            ScenarioError::invalid(
                &format!("reference.{}", e.field()),
                format!("refused by the core: {e}"),
            )
        })?;
        let settle_s = non_negative("reference.settle_s", self.settle_s)?;

        let n = self.waypoints.len();
        let count_error = |what: String| {
            let field = if self.origin.csv.is_some() {
                "reference.waypoints_csv"
            } else {
                "reference.waypoints"
            };
            ScenarioError::invalid(field, what)
        };
        if n < 2 {
            return Err(count_error(format!(
                "a route needs at least two waypoints (got {n}): give [[reference.waypoints]] \
                 tables or waypoints_csv"
            )));
        }
        let capacity = wmr_core::reference::route::ROUTE_CAPACITY;
        if n > capacity {
            return Err(count_error(format!(
                "a route holds at most {capacity} waypoints (got {n})"
            )));
        }
        let core = self.core_waypoints();
        let waypoints = Waypoints::from_slice(&core).map_err(|e| self.route_error(e))?;
        let plan = RoutePlan::new(waypoints.as_slice(), &limits, period_s as f32)
            .map_err(|e| self.route_error(e))?;
        Ok(RouteSetup {
            waypoints,
            limits,
            limits_spec: self.limits_spec(),
            options,
            start: self.start.into(),
            settle_s,
            mavlink: wmr_link::MavlinkSettings::default(),
            plan: Box::new(plan),
        })
    }

    /// The core's refusal, naming the waypoint (1-based) and its key,
    /// with the value.
    fn route_error(&self, e: RouteError) -> ScenarioError {
        let w = |index: u8| self.waypoints.get(usize::from(index));
        match e {
            RouteError::TooFewWaypoints | RouteError::TooManyWaypoints => {
                ScenarioError::invalid("reference.waypoints", e.to_string())
            }
            RouteError::Period => ScenarioError::invalid("period_s", e.to_string()),
            RouteError::TooLong => ScenarioError::invalid("reference", e.to_string()),
            RouteError::NotFinite { index, key } | RouteError::OutOfRange { index, key } => {
                let Some(wp) = w(index) else {
                    return ScenarioError::invalid("reference.waypoints", e.to_string());
                };
                let (name, value, range) = match key {
                    WaypointKey::Position => {
                        let bad_x = !(wmr_core::plausible::COORDINATE_M.contains(wp.x_m as f32));
                        if bad_x {
                            (
                                "x_m",
                                wp.x_m,
                                format!("{} m", wmr_core::plausible::COORDINATE_M),
                            )
                        } else {
                            (
                                "y_m",
                                wp.y_m,
                                format!("{} m", wmr_core::plausible::COORDINATE_M),
                            )
                        }
                    }
                    WaypointKey::Dwell => {
                        ("stop_s", wp.stop_s.unwrap_or(f64::NAN), "[0, ∞) s".into())
                    }
                    WaypointKey::FaceHeading => {
                        let r = wmr_core::plausible::ANGLE_RAD;
                        (
                            "heading_deg",
                            wp.heading_deg.unwrap_or(f64::NAN),
                            format!(
                                "[{}, {}] degrees",
                                shown(f64::from(r.min).to_degrees().round()),
                                shown(f64::from(r.max).to_degrees().round())
                            ),
                        )
                    }
                    WaypointKey::SpeedLimit => (
                        "speed_m_s",
                        wp.speed_m_s.unwrap_or(f64::NAN),
                        "(0, ∞) m/s".into(),
                    ),
                };
                self.waypoint_error(
                    usize::from(index),
                    name,
                    format!("must be finite and in {range} (got {})", shown(value)),
                )
            }
            RouteError::SameAsPrevious { index } => {
                let (x, y) = w(index).map_or((f64::NAN, f64::NAN), |p| (p.x_m, p.y_m));
                self.waypoint_error(
                    usize::from(index),
                    "x_m",
                    format!(
                        "the position ({}, {}) m equals the previous waypoint's: remove one",
                        shown(x),
                        shown(y)
                    ),
                )
            }
            RouteError::NegativeDwell { index } => self.waypoint_error(
                usize::from(index),
                "stop_s",
                format!(
                    "must be ≥ 0 s (got {})",
                    shown(w(index).and_then(|p| p.stop_s).unwrap_or(f64::NAN))
                ),
            ),
            RouteError::SpeedLimit { index } => self.waypoint_error(
                usize::from(index),
                "speed_m_s",
                format!(
                    "must be > 0 m/s (got {})",
                    shown(w(index).and_then(|p| p.speed_m_s).unwrap_or(f64::NAN))
                ),
            ),
            RouteError::BlendDoesNotFit { index } => {
                let (field, prefix) = self.waypoint_field(usize::from(index), "x_m");
                let field = field.strip_suffix(".x_m").unwrap_or(&field).to_owned();
                let prefix = prefix.replace("`x_m` ", "");
                ScenarioError::invalid(
                    &field,
                    format!(
                        "{prefix}the corner blend with blend_deviation_m = {} m does not fit its \
                         legs (or the turn is a reversal): lower blend_deviation_m, move the \
                         waypoints apart, or make this waypoint a stop (stop_s)",
                        shown(self.blend_deviation_m)
                    ),
                )
            }
        }
    }
}

/// The columns a waypoint CSV may have.
const CSV_COLUMNS: [&str; 5] = ["x_m", "y_m", "stop_s", "heading_deg", "speed_m_s"];

/// Parses a waypoint CSV (module documentation): the waypoints and the
/// 1-based line of each.
///
/// # Errors
/// [`ScenarioError::Invalid`] (`reference.waypoints_csv`) naming the file,
/// the line and the column: a header that misses `x_m` or `y_m`, names an
/// unknown or repeated column; a row with a different number of cells; a
/// cell that is not a number; a missing `x_m` or `y_m`.
pub fn parse_waypoints_csv(
    path: &str,
    text: &str,
) -> Result<(Vec<WaypointSpec>, Vec<usize>), ScenarioError> {
    let error = |line: usize, reason: String| {
        ScenarioError::invalid(
            "reference.waypoints_csv",
            format!("{path} line {line}: {reason}"),
        )
    };
    let mut rows = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let Some((header_line, header)) = rows.next() else {
        return Err(error(
            1,
            format!(
                "no header: the first row names the columns ({})",
                CSV_COLUMNS.join(",")
            ),
        ));
    };
    let mut columns: Vec<usize> = Vec::new();
    for name in header.split(',').map(str::trim) {
        let Some(c) = CSV_COLUMNS.iter().position(|k| *k == name) else {
            return Err(error(
                header_line,
                format!(
                    "unknown column `{name}` (the columns: {})",
                    CSV_COLUMNS.join(", ")
                ),
            ));
        };
        if columns.contains(&c) {
            return Err(error(header_line, format!("column `{name}` given twice")));
        }
        columns.push(c);
    }
    for required in [0, 1] {
        if !columns.contains(&required) {
            return Err(error(
                header_line,
                format!("the header has no `{}` column", CSV_COLUMNS[required]),
            ));
        }
    }
    let mut waypoints = Vec::new();
    let mut lines = Vec::new();
    for (line, row) in rows {
        let cells: Vec<&str> = row.split(',').map(str::trim).collect();
        if cells.len() != columns.len() {
            return Err(error(
                line,
                format!(
                    "{} cells, the header has {} columns",
                    cells.len(),
                    columns.len()
                ),
            ));
        }
        let mut values = [None; 5];
        for (&c, cell) in columns.iter().zip(&cells) {
            if cell.is_empty() {
                continue;
            }
            let v: f64 = cell.parse().map_err(|_| {
                error(
                    line,
                    format!("`{}` = `{cell}` is not a number", CSV_COLUMNS[c]),
                )
            })?;
            values[c] = Some(v);
        }
        let [x, y, stop_s, heading_deg, speed_m_s] = values;
        let (Some(x_m), Some(y_m)) = (x, y) else {
            return Err(error(line, "`x_m` and `y_m` must be given".into()));
        };
        waypoints.push(WaypointSpec {
            x_m,
            y_m,
            stop_s,
            heading_deg,
            speed_m_s,
        });
        lines.push(line);
    }
    Ok((waypoints, lines))
}
