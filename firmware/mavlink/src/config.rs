//! The endpoint's configuration, checked once.

use crate::geo::Origin;

/// The endpoint's settings as plain numbers (units in the names).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EndpointSpec {
    /// This robot's MAVLink system id, `1..=255`.
    pub system_id: u8,
    /// This robot's component id, `1..=255` (1 = `MAV_COMP_ID_AUTOPILOT1`).
    pub component_id: u8,
    /// No ground-station heartbeat for this long (after one was seen)
    /// is a link loss, ms, `100..=600_000`.
    pub link_timeout_ms: u32,
    /// During an upload, re-request an item after this long without it,
    /// ms, `50..=60_000`.
    pub item_timeout_ms: u32,
    /// Re-requests of one item before the upload is cancelled, `0..=20`.
    pub item_retries: u8,
    /// Period of the position and attitude telemetry, ms: 0 = off, else
    /// `20..=60_000`.
    pub telemetry_period_ms: u32,
    /// Period of the robot's counters (tracker and RFID reader), ms: each
    /// counter is sent once a period as a `NAMED_VALUE_INT`, the counters
    /// one after another, spread over it; 0 = off, else `20..=60_000`.
    pub counters_period_ms: u32,
    /// The floor's (0, 0) as latitude, longitude in 1e-7 degrees, for the
    /// global frames; `None`: global-frame items are refused
    /// (`MAV_MISSION_UNSUPPORTED_FRAME`).
    pub origin_e7: Option<(i32, i32)>,
}

impl Default for EndpointSpec {
    fn default() -> Self {
        Self {
            system_id: 1,
            component_id: 1,
            link_timeout_ms: 3_000,
            item_timeout_ms: 1_000,
            item_retries: 5,
            telemetry_period_ms: 200,
            counters_period_ms: 5_000,
            origin_e7: None,
        }
    }
}

/// A field of [`EndpointSpec`], as its error names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConfigKey {
    /// `system_id`.
    SystemId,
    /// `component_id`.
    ComponentId,
    /// `link_timeout_ms`.
    LinkTimeout,
    /// `item_timeout_ms`.
    ItemTimeout,
    /// `item_retries`.
    ItemRetries,
    /// `telemetry_period_ms`.
    TelemetryPeriod,
    /// `counters_period_ms`.
    CountersPeriod,
    /// `origin_e7.0` (latitude).
    OriginLatitude,
    /// `origin_e7.1` (longitude).
    OriginLongitude,
}

impl ConfigKey {
    /// The field's name.
    #[must_use]
    pub fn key(self) -> &'static str {
        match self {
            Self::SystemId => "system_id",
            Self::ComponentId => "component_id",
            Self::LinkTimeout => "link_timeout_ms",
            Self::ItemTimeout => "item_timeout_ms",
            Self::ItemRetries => "item_retries",
            Self::TelemetryPeriod => "telemetry_period_ms",
            Self::CountersPeriod => "counters_period_ms",
            Self::OriginLatitude => "origin_e7.latitude",
            Self::OriginLongitude => "origin_e7.longitude",
        }
    }

    /// The accepted range, as text.
    #[must_use]
    pub fn range(self) -> &'static str {
        match self {
            Self::SystemId | Self::ComponentId => "1..=255",
            Self::LinkTimeout => "100..=600000",
            Self::ItemTimeout => "50..=60000",
            Self::ItemRetries => "0..=20",
            Self::TelemetryPeriod | Self::CountersPeriod => "0 or 20..=60000",
            Self::OriginLatitude => "-850000000..=850000000 (±85°)",
            Self::OriginLongitude => "-1800000000..=1800000000 (±180°)",
        }
    }
}

/// A refused setting: the field and its value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConfigError {
    /// The field.
    pub key: ConfigKey,
    /// The value given.
    pub value: i64,
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{} = {} must be in {}",
            self.key.key(),
            self.value,
            self.key.range()
        )
    }
}

impl core::error::Error for ConfigError {}

/// The checked configuration ([`EndpointConfig::new`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EndpointConfig {
    pub(crate) system_id: u8,
    pub(crate) component_id: u8,
    pub(crate) link_timeout_ms: u32,
    pub(crate) item_timeout_ms: u32,
    pub(crate) item_retries: u8,
    pub(crate) telemetry_period_ms: u32,
    pub(crate) counters_period_ms: u32,
    pub(crate) origin: Option<Origin>,
}

impl EndpointConfig {
    /// Every field 0: not a valid configuration ([`Self::new`] refuses
    /// it), the placeholder of an endpoint not configured yet
    /// ([`crate::MavlinkEndpoint::BLANK`]).
    pub(crate) const BLANK: Self = Self {
        system_id: 0,
        component_id: 0,
        link_timeout_ms: 0,
        item_timeout_ms: 0,
        item_retries: 0,
        telemetry_period_ms: 0,
        counters_period_ms: 0,
        origin: None,
    };

    /// The checked configuration.
    ///
    /// # Errors
    /// [`ConfigError`] naming the first field out of its range, with its value.
    // Out of line: inlined into the parameters' set it was copied there.
    #[inline(never)]
    pub fn new(spec: &EndpointSpec) -> Result<Self, ConfigError> {
        let check = |ok: bool, key: ConfigKey, value: i64| {
            if ok {
                Ok(())
            } else {
                Err(ConfigError { key, value })
            }
        };
        check(spec.system_id != 0, ConfigKey::SystemId, 0)?;
        check(spec.component_id != 0, ConfigKey::ComponentId, 0)?;
        check(
            (100..=600_000).contains(&spec.link_timeout_ms),
            ConfigKey::LinkTimeout,
            i64::from(spec.link_timeout_ms),
        )?;
        check(
            (50..=60_000).contains(&spec.item_timeout_ms),
            ConfigKey::ItemTimeout,
            i64::from(spec.item_timeout_ms),
        )?;
        check(
            spec.item_retries <= 20,
            ConfigKey::ItemRetries,
            i64::from(spec.item_retries),
        )?;
        let period = |ms: u32| ms == 0 || (20..=60_000).contains(&ms);
        check(
            period(spec.telemetry_period_ms),
            ConfigKey::TelemetryPeriod,
            i64::from(spec.telemetry_period_ms),
        )?;
        check(
            period(spec.counters_period_ms),
            ConfigKey::CountersPeriod,
            i64::from(spec.counters_period_ms),
        )?;
        let origin = match spec.origin_e7 {
            None => None,
            Some((lat, lon)) => {
                check(
                    (-850_000_000..=850_000_000).contains(&lat),
                    ConfigKey::OriginLatitude,
                    i64::from(lat),
                )?;
                check(
                    (-1_800_000_000..=1_800_000_000).contains(&lon),
                    ConfigKey::OriginLongitude,
                    i64::from(lon),
                )?;
                Some(Origin::new(lat, lon))
            }
        };
        Ok(Self {
            system_id: spec.system_id,
            component_id: spec.component_id,
            link_timeout_ms: spec.link_timeout_ms,
            item_timeout_ms: spec.item_timeout_ms,
            item_retries: spec.item_retries,
            telemetry_period_ms: spec.telemetry_period_ms,
            counters_period_ms: spec.counters_period_ms,
            origin,
        })
    }

    /// The plain numbers of this configuration (to change one and check
    /// the whole again).
    #[must_use]
    pub fn spec(&self) -> EndpointSpec {
        EndpointSpec {
            system_id: self.system_id,
            component_id: self.component_id,
            link_timeout_ms: self.link_timeout_ms,
            item_timeout_ms: self.item_timeout_ms,
            item_retries: self.item_retries,
            telemetry_period_ms: self.telemetry_period_ms,
            counters_period_ms: self.counters_period_ms,
            origin_e7: self.origin.map(|o| (o.lat_e7(), o.lon_e7())),
        }
    }

    /// The geodetic origin, if any.
    #[must_use]
    pub fn origin(&self) -> Option<&Origin> {
        self.origin.as_ref()
    }
}
