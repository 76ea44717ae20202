//! The parameter protocol: list, read, set, refusals by name.

mod common;

use common::*;
use mavlink::dialects::common::*;
use wmr_core::pilot::spec::PilotSpec;
use wmr_core::pilot::tuning::TuningSpec;
use wmr_mavlink::params::PARAMS;
use wmr_mavlink::{COUNTER_NAMES, COUNTERS, Counts, EndpointSpec, Event};

fn id(name: &str) -> [u8; 16] {
    let mut id = [0u8; 16];
    id[..name.len()].copy_from_slice(name.as_bytes());
    id
}

fn values(out: &[MavMessage]) -> Vec<(String, f32, u16, u16)> {
    out.iter()
        .filter_map(|m| match m {
            MavMessage::PARAM_VALUE(p) => Some((
                String::from_utf8_lossy(&p.param_id[..])
                    .trim_end_matches('\0')
                    .to_string(),
                p.param_value,
                p.param_index,
                p.param_count,
            )),
            _ => None,
        })
        .collect()
}

fn set(rig: &mut Rig, name: &str, value: f32) -> (Vec<Event>, Vec<MavMessage>) {
    rig.send(MavMessage::PARAM_SET(PARAM_SET_DATA {
        param_value: value,
        target_system: 1,
        target_component: 1,
        param_id: id(name).into(),
        param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
    }))
}

#[test]
fn list_read_and_set() {
    let mut rig = Rig::default_rig();
    let (_, out) = rig.send(MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
        target_system: 1,
        target_component: 1,
    }));
    let list = values(&out);
    assert_eq!(list.len(), PARAMS.len());
    for (i, (name, _, index, count)) in list.iter().enumerate() {
        assert!(name.len() <= 16);
        assert_eq!(
            (name.as_str(), *index as usize, *count as usize),
            (PARAMS[i].name, i, PARAMS.len())
        );
    }
    assert_eq!(list[0].1, 0.5); // RT_MAX_SPEED, from the rig's limits
    assert_eq!(list[7].1, 3_000.0); // LINK_TIMEOUT_MS, the default

    // Read by name and by index.
    let (_, out) = rig.send(MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
        param_index: -1,
        target_system: 1,
        target_component: 1,
        param_id: id("RT_LAT_ACCEL").into(),
    }));
    assert_eq!(
        values(&out),
        vec![("RT_LAT_ACCEL".into(), 0.5, 2, PARAMS.len() as u16)]
    );
    let (_, out) = rig.send(MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
        param_index: 8,
        target_system: 1,
        target_component: 1,
        param_id: id("").into(),
    }));
    assert_eq!(values(&out)[0].0, "TELEM_PERIOD_MS");

    // A route limit: accepted, the robot told, read back.
    let (events, out) = set(&mut rig, "RT_MAX_SPEED", 0.8);
    assert_eq!(events, vec![Event::RouteLimits]);
    assert_eq!(
        values(&out),
        vec![("RT_MAX_SPEED".into(), 0.8, 0, PARAMS.len() as u16)]
    );
    assert_eq!(rig.ep.route_limits().max_speed_m_s(), 0.8);

    // The link timeout: the endpoint's own, checked by its config.
    let (events, out) = set(&mut rig, "LINK_TIMEOUT_MS", 5_000.0);
    assert!(events.is_empty());
    assert_eq!(values(&out)[0].1, 5_000.0);
    assert_eq!(rig.ep.counters().param_refusals, 0);
}

#[test]
fn refusals_keep_the_old_value_and_name_the_parameter() {
    let mut rig = Rig::default_rig();
    for (name, value) in [
        ("RT_MAX_SPEED", -1.0),
        ("RT_MAX_SPEED", f32::NAN),
        ("RT_PIVOT_THR", 4.0),
        ("LINK_TIMEOUT_MS", 10.0),
        ("LINK_TIMEOUT_MS", 1_500.5),
        ("TELEM_PERIOD_MS", 5.0),
    ] {
        let before = rig.ep.route_limits();
        let (events, out) = set(&mut rig, name, value);
        assert!(events.is_empty(), "{name} = {value}");
        let v = values(&out);
        assert_eq!(v.len(), 1);
        assert_eq!(v[0].0, name);
        assert_ne!(v[0].1.to_bits(), value.to_bits(), "{name}: the old value");
        assert_eq!(rig.ep.route_limits(), before);
        let text = out
            .iter()
            .find_map(|m| match m {
                MavMessage::STATUSTEXT(t) => Some(String::from_utf8_lossy(&t.text[..]).to_string()),
                _ => None,
            })
            .expect("STATUSTEXT");
        assert!(text.contains(name), "{text}");
    }
    assert_eq!(rig.ep.counters().param_refusals, 6);
    // An unknown name: refused by name, no PARAM_VALUE.
    let (_, out) = set(&mut rig, "NO_SUCH", 1.0);
    assert!(values(&out).is_empty());
    assert_eq!(rig.ep.counters().param_refusals, 7);
    // A new timeout applies at once: 100 ms of silence after a GCS
    // heartbeat is a loss once set so.
    set(&mut rig, "LINK_TIMEOUT_MS", 100.0);
    rig.send(MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_GCS,
        ..Default::default()
    }));
    let (events, _) = rig.tick(100);
    assert_eq!(events, vec![Event::LinkLost]);
}

/// The example robot's gains and failsafe times (`PilotSpec::EXAMPLE`:
/// k = 0.5, 0.5, 1; fix timeout 50 ticks, age 2, 0.5 m/s², 5 encoder
/// fault ticks).
fn example_tuning() -> TuningSpec {
    PilotSpec::EXAMPLE.build().unwrap().tuning()
}

/// The STATUSTEXTs of `out`.
/// An unknown name, read or set, is refused by name: the id up to its
/// NUL (all 16 bytes when it has none), what follows the NUL ignored
/// (and a known name followed by bytes after its NUL is found).
#[test]
fn unknown_names_are_refused_by_their_name() {
    let mut rig = Rig::default_rig();
    let mut garbled = id("RT_MAX_SPEED");
    garbled[13..].copy_from_slice(b"XYZ");
    let mut unknown = id("NO_SUCH");
    unknown[9..].copy_from_slice(b"garbage");
    let cases: [([u8; 16], Option<&str>); 4] = [
        (unknown, Some("NO_SUCH")),
        (*b"SIXTEEN_CHARS_XY", Some("SIXTEEN_CHARS_XY")),
        ([0; 16], Some("")),
        (garbled, None),
    ];
    for (k, (param_id, refused)) in cases.into_iter().enumerate() {
        let (_, set_out) = rig.send(MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: 0.5,
            target_system: 1,
            target_component: 1,
            param_id: param_id.into(),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        }));
        let (_, read_out) = rig.send(MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
            param_index: -1,
            target_system: 1,
            target_component: 1,
            param_id: param_id.into(),
        }));
        for out in [set_out, read_out] {
            match refused {
                Some(name) => {
                    assert!(values(&out).is_empty(), "case {k}");
                    assert_eq!(
                        texts(&out),
                        vec![format!("no such parameter: {name}")],
                        "case {k}"
                    );
                }
                None => {
                    assert_eq!(values(&out)[0].0, "RT_MAX_SPEED", "case {k}");
                    assert!(texts(&out).is_empty(), "case {k}");
                }
            }
        }
    }
    assert_eq!(rig.ep.counters().param_refusals, 6);
}

fn texts(out: &[MavMessage]) -> Vec<String> {
    out.iter()
        .filter_map(|m| match m {
            MavMessage::STATUSTEXT(t) => Some(
                String::from_utf8_lossy(&t.text[..])
                    .trim_end_matches('\0')
                    .to_string(),
            ),
            _ => None,
        })
        .collect()
}

/// Each gain and failsafe time: read as the robot's, set through the
/// core's checks into `Event::Tuning` and a PARAM_VALUE of the new value,
/// the endpoint's tuning changed in that one number.
#[test]
fn gains_and_failsafe_times_are_set_through_the_core() {
    let mut rig = Rig::default_rig();
    rig.ep.set_tuning(&example_tuning()).unwrap();
    type Field = fn(&TuningSpec) -> f32;
    let cases: [(&str, f32, f32, Field); 7] = [
        ("TRK_K1", 0.5, 0.25, |t| t.gains.unwrap()[0]),
        ("TRK_K2", 0.5, 0.75, |t| t.gains.unwrap()[1]),
        ("TRK_K3", 1.0, 2.0, |t| t.gains.unwrap()[2]),
        ("FS_FIX_TICKS", 50.0, 20.0, |t| t.fix_timeout_ticks as f32),
        ("FS_FIX_AGE_TICKS", 2.0, 0.0, |t| t.max_fix_age_ticks as f32),
        ("FS_DECEL", 0.5, 1.25, |t| t.failsafe_decel_m_s2),
        ("FS_ENC_TICKS", 5.0, 12.0, |t| {
            t.max_encoder_fault_ticks as f32
        }),
    ];
    for (name, old, new, field) in cases {
        assert!(name.len() <= 16);
        let index = PARAMS.iter().position(|p| p.name == name).unwrap();
        let (_, out) = rig.send(MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
            param_index: -1,
            target_system: 1,
            target_component: 1,
            param_id: id(name).into(),
        }));
        assert_eq!(
            values(&out),
            vec![(name.into(), old, index as u16, PARAMS.len() as u16)]
        );
        let before = *rig.ep.tuning().unwrap().spec();
        let (events, out) = set(&mut rig, name, new);
        assert_eq!(events, vec![Event::Tuning], "{name}");
        assert_eq!(values(&out)[0].1, new, "{name}");
        let after = *rig.ep.tuning().unwrap().spec();
        assert_eq!(field(&after), new, "{name}");
        // Nothing else changed.
        let mut expected = before;
        match name {
            "TRK_K1" => expected.gains.as_mut().unwrap()[0] = new,
            "TRK_K2" => expected.gains.as_mut().unwrap()[1] = new,
            "TRK_K3" => expected.gains.as_mut().unwrap()[2] = new,
            "FS_FIX_TICKS" => expected.fix_timeout_ticks = new as u32,
            "FS_FIX_AGE_TICKS" => expected.max_fix_age_ticks = new as u32,
            "FS_DECEL" => expected.failsafe_decel_m_s2 = new,
            _ => expected.max_encoder_fault_ticks = new as u32,
        }
        assert_eq!(after, expected, "{name}");
    }
    assert_eq!(rig.ep.counters().param_refusals, 0);
}

/// A value the robot file's checks refuse (a gain outside
/// `plausible::GAIN`, NaN, a zero fix timeout, a deceleration outside
/// `plausible::DECEL_M_S2`, a tick count not a whole number): no event,
/// the old value answered, a STATUSTEXT naming the parameter, counted.
#[test]
fn bad_gains_and_failsafe_times_are_refused_by_name() {
    let mut rig = Rig::default_rig();
    rig.ep.set_tuning(&example_tuning()).unwrap();
    let tuning = rig.ep.tuning();
    let bad = [
        ("TRK_K1", -1.0, 0.5),
        ("TRK_K2", f32::NAN, 0.5),
        ("TRK_K3", 1e5, 1.0),
        ("TRK_K3", 0.0, 1.0),
        ("FS_FIX_TICKS", 0.0, 50.0),
        ("FS_FIX_TICKS", 2.5, 50.0),
        ("FS_FIX_AGE_TICKS", -1.0, 2.0),
        ("FS_DECEL", 0.0, 0.5),
        ("FS_DECEL", f32::INFINITY, 0.5),
        ("FS_ENC_TICKS", f32::NAN, 5.0),
    ];
    for (n, (name, value, old)) in bad.into_iter().enumerate() {
        let (events, out) = set(&mut rig, name, value);
        assert!(events.is_empty(), "{name} = {value}");
        let v = values(&out);
        assert_eq!((v.len(), v[0].0.as_str(), v[0].1), (1, name, old));
        assert_eq!(texts(&out), vec![format!("refused: {name}")]);
        assert_eq!(rig.ep.counters().param_refusals, n as u32 + 1);
        assert_eq!(rig.ep.tuning(), tuning, "{name} = {value}: kept");
    }
}

/// Before the robot tells its tuning, and for gains a robot on another
/// law does not have: NaN read, every set refused by name.
#[test]
fn a_tuning_not_told_reads_nan_and_is_refused() {
    let mut rig = Rig::default_rig();
    let (events, out) = set(&mut rig, "FS_DECEL", 1.0);
    assert!(events.is_empty());
    assert!(values(&out)[0].1.is_nan());
    assert_eq!(texts(&out), vec!["refused: FS_DECEL".to_string()]);
    // Another law: no k1..k3; the failsafe times still set.
    let mut no_gains = example_tuning();
    no_gains.gains = None;
    rig.ep.set_tuning(&no_gains).unwrap();
    let (events, out) = set(&mut rig, "TRK_K1", 1.0);
    assert!(events.is_empty());
    assert!(values(&out)[0].1.is_nan());
    assert_eq!(texts(&out), vec!["refused: TRK_K1".to_string()]);
    let (events, _) = set(&mut rig, "FS_DECEL", 1.0);
    assert_eq!(events, vec![Event::Tuning]);
    // A tuning the core refuses is not taken.
    let mut bad = example_tuning();
    bad.fix_timeout_ticks = 0;
    assert!(rig.ep.set_tuning(&bad).is_err());
    assert_eq!(rig.ep.tuning().unwrap().spec().failsafe_decel_m_s2, 1.0);
}

/// The counters go out as NAMED_VALUE_INT, one at a time, each once per
/// `counters_period_ms`, with the robot's values, and not before the
/// robot told them; `CNT_PERIOD_MS` sets the period (0: off).
#[test]
fn counters_go_out_round_robin_at_their_period() {
    let mut rig = Rig::new(EndpointSpec {
        telemetry_period_ms: 0,
        counters_period_ms: 1_500,
        ..EndpointSpec::default()
    });
    let named = |out: &[MavMessage]| -> Vec<(String, i32, u32)> {
        out.iter()
            .filter_map(|m| match m {
                MavMessage::NAMED_VALUE_INT(v) => Some((
                    String::from_utf8_lossy(&v.name[..])
                        .trim_end_matches('\0')
                        .to_string(),
                    v.value,
                    v.time_boot_ms,
                )),
                _ => None,
            })
            .collect()
    };
    // Not told: nothing.
    let (_, out) = rig.tick(0);
    assert!(named(&out).is_empty());
    let mut counts = Counts::default();
    for (i, c) in counts.0.iter_mut().enumerate() {
        *c = 1_000 + i as u32;
    }
    counts.0[1] = u32::MAX; // sent modulo 2^32: -1
    rig.ep.set_counts(counts);
    // 10 ms ticks over 3 s: every counter twice, in order, 100 ms apart.
    let mut got = Vec::new();
    for _ in 0..300 {
        let (_, out) = rig.tick(10);
        let n = named(&out);
        assert!(n.len() <= 1, "one a call");
        got.extend(n);
    }
    assert_eq!(got.len(), 2 * COUNTERS);
    for (k, (name, value, t)) in got.iter().enumerate() {
        let i = k % COUNTERS;
        assert!(name.len() <= 10);
        assert_eq!(name, COUNTER_NAMES[i]);
        assert_eq!(*value, counts.0[i] as i32);
        assert_eq!(*t, 10 + 100 * k as u32);
    }
    assert_eq!(got[1].1, -1);
    // Off by parameter; the period read back.
    let (_, out) = set(&mut rig, "CNT_PERIOD_MS", 0.0);
    assert_eq!(
        values(&out)[0],
        ("CNT_PERIOD_MS".into(), 0.0, 9, PARAMS.len() as u16)
    );
    for _ in 0..300 {
        assert!(named(&rig.tick(10).1).is_empty());
    }
    // Refused like the telemetry period.
    let (_, out) = set(&mut rig, "CNT_PERIOD_MS", 5.0);
    assert_eq!(values(&out)[0].1, 0.0);
    assert_eq!(texts(&out), vec!["refused: CNT_PERIOD_MS".to_string()]);
}
