//! Routes in scenario files (`[reference] kind = "route"`): parsing
//! (inline and CSV alike), each refusal named, and runs that finish.

use std::path::{Path, PathBuf};

use firmware_sim::scenario::robot::Robot;
use firmware_sim::scenario::{ReferenceSpec, keys};
use firmware_sim::simulation::{hil_configuration, hil_route_messages};
use firmware_sim::{Scenario, ScenarioError, run};

/// A scenario on the unicycle with exact positions, tracking `route` (the
/// `[reference]` table's body, waypoints included).
fn scenario(route: &str) -> String {
    format!(
        r#"
name = "r"
duration_s = 60.0
[initial]
x_m = 0.0
y_m = 0.0
heading_rad = 0.0
estimate_cos = 1.0
estimate_sin = 0.0
[controller]
k1 = 2.0
k2 = 2.0
k3 = 1.0
[position]
kind = "exact"
[reference]
kind = "route"
{route}
"#
    )
}

const INLINE: &str = r#"
max_speed_m_s = 0.3
[[reference.waypoints]]
x_m = 0.0
y_m = 0.0
[[reference.waypoints]]
x_m = 1.0
y_m = 0.0
stop_s = 1.0
[[reference.waypoints]]
x_m = 1.0
y_m = 1.0
stop_s = 0.5
heading_deg = 180.0
speed_m_s = 0.2
[[reference.waypoints]]
x_m = 0.0
y_m = 1.0
"#;

const CSV: &str = "# x, y, then optional cells\n\
                   x_m,y_m,stop_s,heading_deg,speed_m_s\n\
                   0.0,0.0,,,\n\
                   1.0,0.0,1.0,,\n\
                   \n\
                   1.0,1.0,0.5,180.0,0.2\n\
                   0.0,1.0,,,\n";

/// A fresh directory under the target dir for this test's files.
fn dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("routes-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn refusal(route: &str) -> ScenarioError {
    Scenario::from_toml_str(&scenario(route)).unwrap_err()
}

fn field(e: &ScenarioError) -> String {
    e.field()
        .unwrap_or_else(|| panic!("no field: {e}"))
        .to_owned()
}

#[test]
fn inline_and_csv_waypoints_are_the_same_route() {
    let inline = Scenario::from_toml_str(&scenario(INLINE)).unwrap();
    let d = dir("csv");
    std::fs::write(d.join("stations.csv"), CSV).unwrap();
    let path = d.join("s.toml");
    std::fs::write(
        &path,
        scenario("max_speed_m_s = 0.3\nwaypoints_csv = \"stations.csv\""),
    )
    .unwrap();
    let from_csv = Scenario::from_file(&path).unwrap();
    assert_eq!(from_csv, inline);
    assert_eq!(from_csv.validate().unwrap(), inline.validate().unwrap());
    let ReferenceSpec::Route(route) = &from_csv.reference else {
        panic!("a route")
    };
    assert_eq!(route.waypoints.len(), 4);
    assert_eq!(route.waypoints[2].heading_deg, Some(180.0));
    assert_eq!(route.waypoints[0].stop_s, None);
    // The resolved file holds the waypoints inline and reads back alike.
    let text = from_csv.to_toml_string().unwrap();
    assert!(!text.contains("waypoints_csv"), "{text}");
    assert_eq!(Scenario::from_toml_str(&text).unwrap(), inline);
}

#[test]
fn unknown_keys_are_refused_by_name() {
    let e = refusal(&format!("colour = \"red\"\n{INLINE}"));
    assert!(
        matches!(&e, ScenarioError::Parse(m) if m.contains("colour")),
        "{e}"
    );
    let e = refusal(&INLINE.replace("stop_s = 1.0", "stop_s = 1.0\ndwell_s = 1.0"));
    assert!(
        matches!(&e, ScenarioError::Parse(m) if m.contains("dwell_s")),
        "{e}"
    );
    let e = refusal(&INLINE.replace("max_speed_m_s", "max_speed"));
    assert!(
        matches!(&e, ScenarioError::Parse(m) if m.contains("max_speed")),
        "{e}"
    );
    let e =
        Scenario::from_toml_str(&scenario(INLINE).replace("kind = \"route\"", "kind = \"rout\""))
            .unwrap_err();
    assert!(e.to_string().contains("`rout`"), "{e}");
}

#[test]
fn a_bad_waypoint_is_named_by_its_index_from_1_and_key_with_its_value() {
    let e = refusal(&INLINE.replace("stop_s = 0.5", "stop_s = -0.5"));
    assert_eq!(field(&e), "reference.waypoints[3].stop_s");
    assert!(e.to_string().contains("-0.5"), "{e}");
    let e = refusal(&INLINE.replace("speed_m_s = 0.2", "speed_m_s = 0.0"));
    assert_eq!(field(&e), "reference.waypoints[3].speed_m_s");
    let e = refusal(&INLINE.replace("heading_deg = 180.0", "heading_deg = nan"));
    assert_eq!(field(&e), "reference.waypoints[3].heading_deg");
    assert!(e.to_string().contains("NaN"), "{e}");
    let e = refusal(&INLINE.replace("x_m = 1.0\ny_m = 1.0", "x_m = 1.0\ny_m = 0.0"));
    assert_eq!(field(&e), "reference.waypoints[3].x_m");
    assert!(e.to_string().contains("previous"), "{e}");
    let e = refusal(&INLINE.replace("x_m = 0.0\ny_m = 1.0", "x_m = 0.0\ny_m = 2e5"));
    assert_eq!(field(&e), "reference.waypoints[4].y_m");
    // A corner whose blend does not fit its legs names the corner.
    let e = refusal(&format!("blend_deviation_m = 0.9\n{INLINE}").replace("stop_s = 1.0", ""));
    assert_eq!(field(&e), "reference.waypoints[2]");
    assert!(e.to_string().contains("blend_deviation_m = 0.9"), "{e}");
    // The limits and options, by their keys, in the file's units.
    let e = refusal(&format!("pivot_threshold_deg = 200.0\n{INLINE}"));
    assert_eq!(field(&e), "reference.pivot_threshold_deg");
    assert!(e.to_string().contains("200"), "{e}");
    let e = refusal(&INLINE.replace("max_speed_m_s = 0.3", "max_speed_m_s = -1.0"));
    assert_eq!(field(&e), "reference.max_speed_m_s");
    let e = refusal(&INLINE.replace("max_speed_m_s = 0.3", "max_speed_m_s = 500.0"));
    assert_eq!(field(&e), "reference.max_speed_m_s");
    let e = refusal(&format!("heading_tolerance_deg = 0.0\n{INLINE}"));
    assert_eq!(field(&e), "reference.heading_tolerance_deg");
    let e = refusal(&format!("pivot_gain_per_s = 2000.0\n{INLINE}"));
    assert_eq!(field(&e), "reference.pivot_gain_per_s");
    let e = refusal(&format!("settle_s = -1.0\n{INLINE}"));
    assert_eq!(field(&e), "reference.settle_s");
}

#[test]
fn a_bad_csv_waypoint_is_named_by_file_line_and_key() {
    let d = dir("bad-csv");
    let path = d.join("s.toml");
    std::fs::write(&path, scenario("waypoints_csv = \"w.csv\"")).unwrap();
    std::fs::write(d.join("w.csv"), CSV.replace("0.5,180.0", "-0.5,180.0")).unwrap();
    let e = Scenario::from_file(&path).unwrap_err();
    assert_eq!(field(&e), "reference.waypoints_csv");
    let text = e.to_string();
    // Line 6 of the file is the third waypoint.
    assert!(
        text.contains("w.csv line 6 (waypoint 3): `stop_s`") && text.contains("-0.5"),
        "{text}"
    );
    std::fs::write(d.join("w.csv"), CSV.replace("1.0,0.0,1.0", "1.0,zero,1.0")).unwrap();
    let text = Scenario::from_file(&path).unwrap_err().to_string();
    assert!(
        text.contains("line 4") && text.contains("`y_m` = `zero`"),
        "{text}"
    );
    std::fs::write(d.join("w.csv"), CSV.replace("speed_m_s", "speed")).unwrap();
    let text = Scenario::from_file(&path).unwrap_err().to_string();
    assert!(text.contains("unknown column `speed`"), "{text}");
}

#[test]
fn both_inline_and_csv_waypoints_are_refused() {
    let d = dir("both");
    std::fs::write(d.join("w.csv"), CSV).unwrap();
    let path = d.join("s.toml");
    std::fs::write(
        &path,
        scenario(&format!("waypoints_csv = \"w.csv\"\n{INLINE}")),
    )
    .unwrap();
    let e = Scenario::from_file(&path).unwrap_err();
    assert_eq!(field(&e), "reference.waypoints_csv");
    assert!(e.to_string().contains("give one"), "{e}");
}

#[test]
fn a_missing_csv_is_named_with_its_path() {
    let d = dir("missing");
    let path = d.join("s.toml");
    std::fs::write(&path, scenario("waypoints_csv = \"nowhere.csv\"")).unwrap();
    let e = Scenario::from_file(&path).unwrap_err();
    let text = e.to_string();
    assert!(matches!(e, ScenarioError::Io { .. }), "{text}");
    assert!(
        text.contains(&d.join("nowhere.csv").display().to_string())
            && text.contains("reference.waypoints_csv"),
        "{text}"
    );
    // A text read without its file cannot read a CSV.
    let e = refusal("waypoints_csv = \"w.csv\"");
    assert_eq!(field(&e), "reference.waypoints_csv");
}

#[test]
fn fewer_than_two_waypoints_are_refused() {
    let e = refusal("max_speed_m_s = 0.3");
    assert_eq!(field(&e), "reference.waypoints");
    assert!(e.to_string().contains("got 0"), "{e}");
    let e = refusal("[[reference.waypoints]]\nx_m = 1.0\ny_m = 2.0");
    assert_eq!(field(&e), "reference.waypoints");
    assert!(e.to_string().contains("got 1"), "{e}");
}

#[test]
fn state_feedback_refuses_a_route() {
    let text = scenario(INLINE).replace("k1 = 2.0", "kind = \"state_feedback\"\nk1 = 2.0");
    let e = Scenario::from_toml_str(&text).unwrap_err();
    assert_eq!(field(&e), "controller.kind");
}

/// The HIL link's messages for a route: the announcement (the route's
/// spec), then every waypoint in order in chunks of
/// `ROUTE_CHUNK_WAYPOINTS`; the firmware's session (its code, on the
/// host) loads them after the configuration, answering `RouteLoaded` with
/// the count so far and `Configured` for the last.
#[test]
fn the_hil_link_carries_a_route() {
    use std::cell::RefCell;
    use wmr_link::proxy::ProxyBus;
    use wmr_link::session::{LinkTagMap, RouteStore, Session};
    use wmr_link::{HostMessage, LinkCounters, ROUTE_CHUNK_WAYPOINTS, TargetMessage};

    let setup = Scenario::embedded("route").unwrap().validate().unwrap();
    let route = setup.route.as_ref().unwrap();
    let n = route.waypoints.as_slice().len();
    let messages = hil_route_messages(&setup);
    assert_eq!(messages.len(), 1 + n.div_ceil(ROUTE_CHUNK_WAYPOINTS));
    let Some(HostMessage::Route(spec)) = messages.first() else {
        panic!("the announcement first: {messages:?}")
    };
    assert_eq!(*spec, route.spec());
    assert_eq!(usize::from(spec.waypoints), n);
    let sent: Vec<_> = messages[1..]
        .iter()
        .flat_map(|m| match m {
            HostMessage::RouteChunk(c) => c.waypoints.to_vec(),
            other => panic!("a chunk: {other:?}"),
        })
        .collect();
    assert_eq!(sent.as_slice(), route.waypoints.as_slice());

    let bus = ProxyBus::new();
    let map = RefCell::new(LinkTagMap::new());
    let mut store = Box::new(RouteStore::new());
    let mut session = Session::new(&bus, &map, &mut store);
    let configure = HostMessage::Configure(hil_configuration(&setup).unwrap());
    let answers: Vec<TargetMessage> = std::iter::once(configure)
        .chain(messages)
        .map(|m| session.handle(&m, LinkCounters::default(), || 0).0)
        .collect();
    let mut expected = vec![TargetMessage::Configured];
    expected.extend(
        (0..n)
            .step_by(ROUTE_CHUNK_WAYPOINTS)
            .map(|w| TargetMessage::RouteLoaded {
                waypoints: u8::try_from(w).unwrap(),
            }),
    );
    expected.push(TargetMessage::Configured);
    assert_eq!(answers, expected);
    assert!(session.is_configured());
    assert!(session.route_status().is_some_and(|s| !s.done));
}

/// A robot file's route rides in its flash image: decoded as the board
/// decodes it, the image announces the route's spec and holds its
/// waypoints, in order, beside the pilot.
#[test]
fn a_robot_file_reads_its_route_and_flashes_it() {
    let d = dir("robot");
    let example = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/example.toml"),
    )
    .unwrap();
    std::fs::write(d.join("w.csv"), CSV).unwrap();
    // The example's own [reference] table, replaced by a route.
    let start = example.find("\n[reference]").unwrap();
    let end = example[start + 1..]
        .find("\n[")
        .map_or(example.len(), |e| start + 1 + e);
    let robot_text = format!(
        "{}{}\n[reference]\nkind = \"route\"\nwaypoints_csv = \"w.csv\"\n",
        &example[..start],
        &example[end..]
    );
    std::fs::write(d.join("robot.toml"), &robot_text).unwrap();
    let robot = Robot::from_file(&d.join("robot.toml")).unwrap();
    let flash = robot.flash_image().unwrap();
    let (spec, waypoints) = flash.route.clone().expect("the image's route");
    assert_eq!(usize::from(spec.waypoints), 4);
    assert_eq!(waypoints.len(), 4);
    // The route as every simulation of the robot validates it.
    let ReferenceSpec::Route(file_route) = robot.file.reference.clone().unwrap() else {
        panic!("a route")
    };
    let setup = file_route.validate(robot.file.period_s).unwrap();
    assert_eq!(spec, setup.spec());
    assert_eq!(waypoints.as_slice(), setup.waypoints.as_slice());
    let image = wmr_link::image::decode(&flash.bytes).unwrap();
    assert_eq!(image.pilot, flash.pilot);
    let route = image.route.expect("a route in the decoded image");
    assert_eq!(route.spec, spec);
    assert_eq!(route.waypoints().collect::<Vec<_>>(), waypoints);
    // A bad waypoint is named in the robot file.
    std::fs::write(d.join("w.csv"), CSV.replace("0.5,180.0", "-0.5,180.0")).unwrap();
    let e = Robot::from_file(&d.join("robot.toml")).unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("robot file")
            && text.contains("reference.waypoints_csv")
            && text.contains("stop_s"),
        "{text}"
    );
    let listed: Vec<String> = keys::robot_keys().into_iter().map(|k| k.key).collect();
    for key in [
        "reference.waypoints.heading_deg",
        "reference.waypoints_csv",
        "reference.pivot_threshold_deg",
    ] {
        assert!(listed.iter().any(|k| k == key), "{key} not listed");
    }
}

/// On the unicycle with exact positions and the heading known, the route
/// finishes on its plan's time and stops within the product goals (1 cm,
/// 1°), measured on the true pose.
#[test]
fn a_route_run_finishes_with_its_stops_within_tolerance() {
    let scenario = Scenario::from_toml_str(&scenario(INLINE)).unwrap();
    let r = run(&scenario, |_, _| {}).unwrap();
    let route = r.summary.route.clone().unwrap();
    assert!(route.done, "{route:?}");
    assert_eq!(route.counters.routes_done, 1);
    assert_eq!(route.counters.stops_reached, 3, "{route:?}");
    assert_eq!(route.counters.pivots, 2, "{route:?}");
    assert_eq!(route.stops.len(), 3);
    for stop in &route.stops {
        let e = stop.position_error_m.unwrap();
        assert!(e < 0.01, "{stop:?}");
        if let Some(h) = stop.heading_error_deg {
            assert!(h < 1.0, "{stop:?}");
        }
    }
    assert!(route.stops[1].heading_error_deg.is_some());
    let ratio = route.time_ratio.unwrap();
    assert!((1.0..1.05).contains(&ratio), "{ratio}");
    // The run ends settle_s (2 s) after the route is done.
    let done_at = route.done_at_s.unwrap();
    let end = r.records.last().unwrap().t_s;
    assert!((end - done_at - 2.0).abs() < 0.011, "{end} {done_at}");
    assert!(route.max_cross_track_error_m.unwrap() < 0.02, "{route:?}");
}

/// A route that cannot finish within the duration is reported so.
#[test]
fn a_route_not_done_within_the_duration_is_reported() {
    let text = scenario(INLINE).replace("duration_s = 60.0", "duration_s = 5.0");
    let r = run(&Scenario::from_toml_str(&text).unwrap(), |_, _| {}).unwrap();
    let route = r.summary.route.unwrap();
    assert!(!route.done && route.time_taken_s.is_none() && route.stops_missed > 0);
    assert_eq!(r.records.len(), 500);
}

/// A sweep of a route aggregates its figures: the worst over all stops of
/// all runs, each with its run, and the runs done.
#[test]
fn a_route_sweep_aggregates_the_route_figures() {
    use firmware_sim::sweep::{SweepOptions, run_sweep};
    let s = Scenario::embedded("route").unwrap();
    let options = SweepOptions {
        runs: 3,
        seed: 1,
        threads: 1,
    };
    let result = run_sweep(&s, &options, &|| {}).unwrap();
    let route = result.summary.route.clone().unwrap();
    assert_eq!(route.runs_done + route.not_done.len() as u64, 3);
    let per_run: Vec<f64> = result
        .rows
        .iter()
        .map(|r| r.route.unwrap().max_stop_position_error_m.unwrap())
        .collect();
    let worst = route.worst_stop_position_error_m.unwrap();
    assert_eq!(worst.value, per_run.iter().copied().fold(0.0, f64::max));
    assert_eq!(per_run[worst.index as usize], worst.value);
    assert!(route.worst_cross_track_error_m.is_some() && route.worst_time_ratio.is_some());
    // The route figures are in summary.json, not in runs.csv.
    let json = serde_json::to_value(&result.summary).unwrap();
    assert!(json["route"]["worst_stop_heading_error_deg"]["value"].is_number());
}
