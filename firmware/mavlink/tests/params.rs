//! The parameter protocol: list, read, set, refusals by name.

mod common;

use common::*;
use mavlink::dialects::common::*;
use wmr_mavlink::Event;
use wmr_mavlink::params::PARAMS;

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
    assert_eq!(values(&out), vec![("RT_LAT_ACCEL".into(), 0.5, 2, 9)]);
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
    assert_eq!(values(&out), vec![("RT_MAX_SPEED".into(), 0.8, 0, 9)]);
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
