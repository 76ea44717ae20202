//! The parameter protocol (<https://mavlink.io/en/services/parameter.html>):
//! `PARAM_REQUEST_LIST`, `PARAM_REQUEST_READ` and `PARAM_SET`, answered
//! with `PARAM_VALUE`, over the table [`PARAMS`].
//!
//! Every value is a `MAV_PARAM_TYPE_REAL32`. A set value is checked by the
//! constructor that checks it in a robot file ([`RouteLimits::new`],
//! [`EndpointConfig::new`], [`TuningSpec::build`]: the spec as it stands
//! with the one value changed, checked whole); a refusal is answered with
//! the old value and a `STATUSTEXT` naming the parameter, and counted. A
//! route limit accepted is [`Event::RouteLimits`]: the robot takes
//! [`MavlinkEndpoint::route_limits`] for its next route; a gain or
//! failsafe time accepted is [`Event::Tuning`]: the robot takes
//! [`MavlinkEndpoint::tuning`] from its next tick.

use mavlink::MessageData;
use mavlink::dialects::common as c;
use wmr_core::pilot::tuning::TuningSpec;
use wmr_core::reference::route::{RouteLimits, RouteLimitsSpec};

use crate::config::EndpointConfig;
use crate::endpoint::{Event, Events, MavlinkEndpoint};
use crate::wire::{self, RxFrame, TxBuffer};

/// One parameter: its MAVLink name (≤ 16 characters) and what it sets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Param {
    /// The name a ground station shows.
    pub name: &'static str,
    /// The field it sets, with its unit.
    pub key: &'static str,
}

/// The parameters, in index order.
pub const PARAMS: [Param; 17] = [
    Param {
        name: "RT_MAX_SPEED",
        key: "route max_speed_m_s",
    },
    Param {
        name: "RT_TAN_ACCEL",
        key: "route max_tangential_accel_m_s2",
    },
    Param {
        name: "RT_LAT_ACCEL",
        key: "route max_lateral_accel_m_s2",
    },
    Param {
        name: "RT_BLEND_DEV",
        key: "route blend_deviation_m",
    },
    Param {
        name: "RT_PIVOT_THR",
        key: "route pivot_threshold_rad",
    },
    Param {
        name: "RT_PIVOT_RATE",
        key: "route pivot_rate_rad_s",
    },
    Param {
        name: "RT_PIVOT_ACC",
        key: "route pivot_accel_rad_s2",
    },
    Param {
        name: "LINK_TIMEOUT_MS",
        key: "link_timeout_ms",
    },
    Param {
        name: "TELEM_PERIOD_MS",
        key: "telemetry_period_ms",
    },
    Param {
        name: "CNT_PERIOD_MS",
        key: "counters_period_ms",
    },
    Param {
        name: "TRK_K1",
        key: "tracker gains[0] (k1, m/s)",
    },
    Param {
        name: "TRK_K2",
        key: "tracker gains[1] (k2, m/s)",
    },
    Param {
        name: "TRK_K3",
        key: "tracker gains[2] (k3, 1/s)",
    },
    Param {
        name: "FS_FIX_TICKS",
        key: "tracker fix_timeout_ticks",
    },
    Param {
        name: "FS_FIX_AGE_TICKS",
        key: "tracker max_fix_age_ticks",
    },
    Param {
        name: "FS_DECEL",
        key: "tracker failsafe_decel_m_s2",
    },
    Param {
        name: "FS_ENC_TICKS",
        key: "max_encoder_fault_ticks",
    },
];

const LINK_TIMEOUT: usize = 7;
const TELEMETRY_PERIOD: usize = 8;
const COUNTERS_PERIOD: usize = 9;
/// The first of the tuning's parameters ([`TuningSpec`]): `TRK_K1`.
const TUNING: usize = 10;

/// The parameters' names as `param_id` carries them: NUL-padded to 16
/// bytes, in index order, made from [`PARAMS`] at build time. The firmware
/// links this table alone: [`PARAMS`]' keys and string addresses are for
/// the host, and a search over the names as strings was unrolled by
/// LLVM into one comparison per name.
const NAMES: [[u8; 16]; PARAMS.len()] = names();

/// [`NAMES`] from [`PARAMS`]; a name past 16 characters fails the build.
const fn names() -> [[u8; 16]; PARAMS.len()] {
    let mut out = [[0; 16]; PARAMS.len()];
    let mut i = 0;
    while i < PARAMS.len() {
        out[i] = wire::nul_padded(PARAMS[i].name);
        i += 1;
    }
    out
}

/// The index of the parameter whose 16-byte, NUL-padded id is `id` (what
/// follows its first NUL ignored).
// Out of line: inlined into its two callers it was copied in each.
#[inline(never)]
fn find(id: &[u8]) -> Option<usize> {
    // An opaque id: with its length known (16), LLVM unrolls the search
    // for its NUL a byte at a time.
    let id = core::hint::black_box(id);
    let len = id.iter().position(|&b| b == 0).unwrap_or(id.len());
    let mut key = [0u8; 16];
    // An id of more than 16 bytes before its NUL leaves the key zero: no
    // name matches.
    if let (Some(dst), Some(src)) = (key.get_mut(..len), id.get(..len)) {
        dst.copy_from_slice(src);
    }
    let key = u128::from_le_bytes(key);
    // An opaque table: with its length and contents known, LLVM unrolls
    // the search into one comparison per name.
    core::hint::black_box(&NAMES[..])
        .iter()
        .position(|name| u128::from_le_bytes(*name) == key)
}

fn limit(spec: &RouteLimitsSpec, index: usize) -> f32 {
    match index {
        0 => spec.max_speed_m_s,
        1 => spec.max_tangential_accel_m_s2,
        2 => spec.max_lateral_accel_m_s2,
        3 => spec.blend_deviation_m,
        4 => spec.pivot_threshold_rad,
        5 => spec.pivot_rate_rad_s,
        _ => spec.pivot_accel_rad_s2,
    }
}

fn limit_mut(spec: &mut RouteLimitsSpec, index: usize) -> &mut f32 {
    match index {
        0 => &mut spec.max_speed_m_s,
        1 => &mut spec.max_tangential_accel_m_s2,
        2 => &mut spec.max_lateral_accel_m_s2,
        3 => &mut spec.blend_deviation_m,
        4 => &mut spec.pivot_threshold_rad,
        5 => &mut spec.pivot_rate_rad_s,
        _ => &mut spec.pivot_accel_rad_s2,
    }
}

/// The plain numbers of checked limits.
pub(crate) fn spec_of(limits: &RouteLimits) -> RouteLimitsSpec {
    RouteLimitsSpec {
        max_speed_m_s: limits.max_speed_m_s(),
        max_tangential_accel_m_s2: limits.max_tangential_accel_m_s2(),
        max_lateral_accel_m_s2: limits.max_lateral_accel_m_s2(),
        blend_deviation_m: limits.blend_deviation_m(),
        pivot_threshold_rad: limits.pivot_threshold_rad(),
        pivot_rate_rad_s: limits.pivot_rate_rad_s(),
        pivot_accel_rad_s2: limits.pivot_accel_rad_s2(),
    }
}

/// Tuning parameter `i` (0 = `TRK_K1`) of `spec`; `None` for a gain of a
/// robot without law (27)–(28)'s.
fn tuning_value(spec: &TuningSpec, i: usize) -> Option<f32> {
    Some(match i {
        0..=2 => *spec.gains?.get(i)?,
        3 => spec.fix_timeout_ticks as f32,
        4 => spec.max_fix_age_ticks as f32,
        5 => spec.failsafe_decel_m_s2,
        _ => spec.max_encoder_fault_ticks as f32,
    })
}

/// Sets tuning parameter `i` of `spec` to `value`; `false` for a gain of
/// a robot without law (27)–(28)'s, or a tick count that is not a whole
/// number in `u32` (the rest is [`TuningSpec::build`]'s to check).
fn set_tuning(spec: &mut TuningSpec, i: usize, value: f32) -> bool {
    let ticks = millis(value);
    let slot = match i {
        0..=2 => {
            return match spec.gains.as_mut().and_then(|g| g.get_mut(i)) {
                Some(k) => {
                    *k = value;
                    true
                }
                None => false,
            };
        }
        5 => {
            spec.failsafe_decel_m_s2 = value;
            return true;
        }
        3 => &mut spec.fix_timeout_ticks,
        4 => &mut spec.max_fix_age_ticks,
        _ => &mut spec.max_encoder_fault_ticks,
    };
    match ticks {
        Some(t) => {
            *slot = t;
            true
        }
        None => false,
    }
}

/// `PARAM_VALUE`'s payload as little-endian words: `param_value` f32,
/// `param_count` and `param_index` u16, `param_id` (16 bytes), and
/// `param_type` `MAV_PARAM_TYPE_REAL32`.
fn param_value_words(value: f32, index: usize, name: &[u8; 16]) -> [u32; 7] {
    let id = |k: usize| {
        let b = |j: usize| name.get(4 * k + j).copied().unwrap_or(0);
        u32::from_le_bytes([b(0), b(1), b(2), b(3)])
    };
    [
        value.to_bits(),
        PARAMS.len() as u32 | ((index as u32) << 16),
        id(0),
        id(1),
        id(2),
        id(3),
        c::MavParamType::MAV_PARAM_TYPE_REAL32 as u32,
    ]
}

/// A whole number (of milliseconds, or ticks) in `u32`, or `None`.
// Out of line: inlined into its two callers it was copied in each.
#[inline(never)]
fn millis(value: f32) -> Option<u32> {
    // In range, `as` truncates toward zero (and takes 2^32, the nearest
    // `f32` to `u32::MAX`, to `u32::MAX`), so the value is whole exactly
    // when it converts back to itself; NaN fails every comparison.
    let whole = value as u32;
    (value >= 0.0 && value <= u32::MAX as f32 && whole as f32 == value).then_some(whole)
}

impl MavlinkEndpoint {
    /// The route limits, as last set (at construction or by `PARAM_SET`).
    #[must_use]
    pub fn route_limits(&self) -> RouteLimits {
        self.limits
    }

    fn param_value(&self, index: usize) -> f32 {
        match index {
            LINK_TIMEOUT => self.config.link_timeout_ms as f32,
            TELEMETRY_PERIOD => self.config.telemetry_period_ms as f32,
            COUNTERS_PERIOD => self.config.counters_period_ms as f32,
            i if i >= TUNING => self
                .tuning
                .get()
                .and_then(|t| tuning_value(t.spec(), i - TUNING))
                .unwrap_or(f32::NAN),
            i => limit(&spec_of(&self.limits), i),
        }
    }

    // Out of line: called from many places; inlined at each (opt-level 3,
    // fat LTO) it cost flash (docs/mavlink.md, Cost).
    #[inline(never)]
    fn send_param(&mut self, tx: &mut TxBuffer<'_>, index: usize) {
        let Some(name) = NAMES.get(index) else {
            return;
        };
        let words = param_value_words(self.param_value(index), index, name);
        self.send_words(
            tx,
            c::PARAM_VALUE_DATA::ID,
            c::PARAM_VALUE_DATA::EXTRA_CRC,
            &words,
        );
    }

    // Out of line: called from three places.
    #[inline(never)]
    fn param_refused(&mut self, tx: &mut TxBuffer<'_>, what: &[u8], id: &[u8]) {
        self.counters.param_refusals = self.counters.param_refusals.wrapping_add(1);
        // `what`, then the id up to its NUL (16 bytes at most).
        let name = id.iter().take(16).take_while(|&&b| b != 0);
        let mut text = [0u8; 50];
        let mut n = 0;
        for (slot, &b) in text.iter_mut().zip(what.iter().chain(name)) {
            *slot = b;
            n += 1;
        }
        self.status_text(
            tx,
            c::MavSeverity::MAV_SEVERITY_WARNING,
            text.get(..n).unwrap_or(&[]),
        );
    }

    // Out of line: at opt-level 3 with fat LTO, inlined into its caller it
    // is unrolled and duplicated (docs/mavlink.md, Cost).
    #[inline(never)]
    pub(crate) fn on_param(&mut self, frame: &RxFrame, tx: &mut TxBuffer<'_>, events: &mut Events) {
        match frame.msg_id {
            c::PARAM_REQUEST_LIST_DATA::ID => {
                if self.for_us(frame.byte(0), frame.byte(1)) {
                    // An opaque count: LLVM unrolls the loop into one call
                    // per parameter otherwise.
                    for index in 0..core::hint::black_box(PARAMS.len()) {
                        self.send_param(tx, index);
                    }
                }
            }
            c::PARAM_REQUEST_READ_DATA::ID => {
                // param_index i16 @0, target @2, @3, param_id @4..20.
                if !self.for_us(frame.byte(2), frame.byte(3)) {
                    return;
                }
                let id = frame.payload.get(4..20).unwrap_or(&[]);
                let index = frame.u16_at(0) as i16;
                let found = if index >= 0 {
                    usize::try_from(index).ok().filter(|&i| i < PARAMS.len())
                } else {
                    find(id)
                };
                match found {
                    Some(i) => self.send_param(tx, i),
                    None => self.param_refused(tx, b"no such parameter: ", id),
                }
            }
            _ => {
                // PARAM_SET: param_value f32 @0, target @4, @5, param_id
                // @6..22, param_type @22.
                if !self.for_us(frame.byte(4), frame.byte(5)) {
                    return;
                }
                let mut id = [0u8; 16];
                if let Some(s) = frame.payload.get(6..22) {
                    id.copy_from_slice(s);
                }
                let value = f32::from_le_bytes([
                    frame.byte(0),
                    frame.byte(1),
                    frame.byte(2),
                    frame.byte(3),
                ]);
                let Some(index) = find(&id) else {
                    return self.param_refused(tx, b"no such parameter: ", &id);
                };
                if self.set_param(index, value, events) {
                    self.send_param(tx, index);
                } else {
                    // The old value, so that the ground station shows what holds.
                    self.send_param(tx, index);
                    self.param_refused(tx, b"refused: ", &id);
                }
            }
        }
    }

    /// Sets parameter `index` if its constructor accepts the value.
    fn set_param(&mut self, index: usize, value: f32, events: &mut Events) -> bool {
        match index {
            i if i >= TUNING => {
                let Some(mut spec) = self.tuning.get().map(|t| *t.spec()) else {
                    return false;
                };
                if !set_tuning(&mut spec, i - TUNING, value) {
                    return false;
                }
                match spec.build() {
                    Ok(tuning) if events.push(Event::Tuning) => {
                        self.tuning = crate::endpoint::TuningSlot::Told(tuning);
                        true
                    }
                    _ => false,
                }
            }
            LINK_TIMEOUT | TELEMETRY_PERIOD | COUNTERS_PERIOD => {
                let Some(ms) = millis(value) else {
                    return false;
                };
                let mut spec = self.config.spec();
                match index {
                    LINK_TIMEOUT => spec.link_timeout_ms = ms,
                    TELEMETRY_PERIOD => spec.telemetry_period_ms = ms,
                    _ => spec.counters_period_ms = ms,
                }
                match EndpointConfig::new(&spec) {
                    Ok(config) => {
                        self.config = config;
                        true
                    }
                    Err(_) => false,
                }
            }
            i => {
                let mut spec = spec_of(&self.limits);
                *limit_mut(&mut spec, i) = value;
                match RouteLimits::new(&spec) {
                    Ok(limits) if events.push(Event::RouteLimits) => {
                        self.limits = limits;
                        true
                    }
                    _ => false,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use mavlink::MessageData;
    use mavlink::dialects::common as c;

    use super::{NAMES, PARAMS, find, millis, param_value_words};

    /// The whole-number check is the definition's: finite, in `u32`'s
    /// range and equal to its truncation.
    #[test]
    fn whole_numbers_are_the_truncations_that_fit() {
        let reference = |v: f32| {
            (v.is_finite() && v >= 0.0 && v <= u32::MAX as f32 && libm::truncf(v) == v)
                .then_some(v as u32)
        };
        let values = [
            0.0,
            -0.0,
            0.5,
            1.0,
            1.5,
            -1.0,
            -0.5,
            999.999,
            1_000.0,
            16_777_216.0,
            16_777_218.0,
            2_147_483_648.0,
            4_294_967_040.0,
            4_294_967_296.0,
            8_589_934_592.0,
            f32::MAX,
            f32::MIN,
            f32::MIN_POSITIVE,
            f32::EPSILON,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        let mut bits: u32 = 1;
        let drawn = core::iter::repeat_with(|| {
            bits = bits.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            [f32::from_bits(bits), f32::from_bits(bits >> 3) % 70_000.0]
        });
        for v in values.into_iter().chain(drawn.take(20_000).flatten()) {
            assert_eq!(millis(v), reference(v), "{v:e} ({:#x})", v.to_bits());
        }
    }

    /// The names' table holds every name, NUL-padded, and the search finds
    /// each by its wire id, with or without bytes after its NUL.
    #[test]
    fn the_names_table_is_the_parameters() {
        for (i, p) in PARAMS.iter().enumerate() {
            let mut id = [0u8; 16];
            id[..p.name.len()].copy_from_slice(p.name.as_bytes());
            assert_eq!(NAMES[i], id, "{}", p.name);
            assert_eq!(find(&id), Some(i), "{}", p.name);
            if p.name.len() < 15 {
                id[p.name.len() + 1] = b'X';
                assert_eq!(find(&id), Some(i), "{} with bytes after its NUL", p.name);
            }
        }
        assert_eq!(find(b"RT_MAX_SPEE\0\0\0\0\0"), None);
        assert_eq!(find(b"RT_MAX_SPEEDX\0\0\0"), None);
        assert_eq!(find(&[0; 16]), None);
        assert_eq!(find(&[]), None);
    }

    #[test]
    fn param_values_are_the_librarys_encoding() {
        for (index, p) in PARAMS.iter().enumerate() {
            for value in [0.0, -1.5, 1e9, f32::NAN, f32::MIN_POSITIVE] {
                let mut id = [0u8; 16];
                id[..p.name.len()].copy_from_slice(p.name.as_bytes());
                let mut ours = [0u8; 255];
                for (bytes, word) in
                    ours.chunks_exact_mut(4)
                        .zip(param_value_words(value, index, &NAMES[index]))
                {
                    bytes.copy_from_slice(&word.to_le_bytes());
                }
                let mut lib = [0u8; 255];
                let _ = c::PARAM_VALUE_DATA {
                    param_value: value,
                    param_count: PARAMS.len() as u16,
                    param_index: index as u16,
                    param_id: id.into(),
                    param_type: c::MavParamType::MAV_PARAM_TYPE_REAL32,
                }
                .ser(mavlink::MavlinkVersion::V2, &mut lib);
                assert_eq!(ours, lib, "{} = {value}", p.name);
            }
        }
    }
}
