use super::report::parse;
use super::*;

const OUTPUT: &str = "\
wmr-bench backend=libm samples=200
calibration counts_per_instruction=0.16800 loop_counts_per_iteration=0.33601 nop_counts_per_instruction=0.1683 overhead_instructions=2.0
bench odometry mean=73.7 median=75 min=69 max=75 n=200
bench robot_tick mean=10227.0 median=9266 min=9052 max=11432 n=200
bench pf3_predict mean=936441.6 median=936579 min=933347 max=938829 n=200
bench pf3_update mean=277137.9 median=276744 min=274988 max=283708 n=200
stack pf3_predict bytes=328
stack pf3_update bytes=352
filter pf3 state_bytes=2928 position_rms_error_m=0.0428 faults=0 repairs=0 resamplings=61 steps=601
stack robot_tick bytes=776
check frames_ok=230 unknown_tags=0 encoder_errors=0 mode=tracking
done
";

#[test]
fn parses_the_bench_output() {
    let r = parse(OUTPUT).unwrap();
    assert_eq!(r.backend, "libm");
    assert_eq!(r.samples, 200);
    assert_eq!(r.tick_stack_bytes, 776);
    let tick = r.stat("robot_tick").unwrap();
    assert_eq!((tick.min, tick.max), (9052, 11432));
    assert!((tick.mean - 10227.0).abs() < 1e-9);
    let md = markdown(&[r]);
    assert!(md.contains("| 10 227 (9 052–11 432) |"), "{md}");
    assert!(md.contains("| 776 B |"), "{md}");
}

#[test]
fn reports_the_filters() {
    let r = parse(OUTPUT).unwrap();
    assert_eq!(r.stack("pf3_update"), Some(352));
    assert_eq!(r.filter("pf3").map(|f| f.state_bytes), Some(2928));
    let md = markdown(&[r]);
    assert!(
        md.contains(
            "| particle filter, N = M = 3, 100 particles (prior proposal): predict | 936 442 (933 347–938 829) |"
        ),
        "{md}"
    );
    assert!(
        md.contains("| particle filter, N = M = 3, 100 particles (prior proposal) | 2 928 B | 328 B / 352 B | 0.043 m (61 resamplings in 601 updates) |"),
        "{md}"
    );
    assert!(
        md.contains("| EKF, N = M = 3 (`PoseModel`): update | – |"),
        "{md}"
    );
}

/// The particle filter's own build gives its whole-tick rows and stack
/// to its backend's column, nothing else; a build lacking them, or a
/// main build that measured them itself, is an error.
#[test]
fn the_particle_filter_build_gives_its_tick_rows() {
    let pf_output = OUTPUT.replace(
        "stack robot_tick bytes=776\n",
        "stack robot_tick bytes=9999\n\
         bench robot_tick_fusion_pf_fix mean=268219.0 median=268000 min=248820 max=359407 n=100\n\
         bench robot_tick_fusion_pf_dead_reckoned mean=159212.0 median=159200 min=157673 max=159804 n=100\n\
         stack robot_tick_fusion_pf bytes=15296\n",
    );
    let pf = parse(&pf_output).unwrap();
    let mut r = parse(OUTPUT).unwrap();
    r.take_pf_tick(&pf).unwrap();
    assert_eq!(r.stack("robot_tick_fusion_pf"), Some(15296));
    assert_eq!(r.tick_stack_bytes, 776, "the main build's own tick");
    assert_eq!(
        r.stat("robot_tick_fusion_pf_fix").map(|s| s.max),
        Some(359_407)
    );
    let md = markdown(&[r.clone()]);
    assert!(
        md.contains(
            "tick with a tag fix (the read tag's cell likelihood) | 268 219 (248 820–359 407) |"
        ),
        "{md}"
    );
    assert!(md.contains("| tick peak stack, fusion particle filter estimator (below the caller's SP) | 15 296 B |"), "{md}");
    assert!(r.take_pf_tick(&pf).is_err(), "measured twice");
    assert!(
        parse(OUTPUT)
            .unwrap()
            .take_pf_tick(&parse(OUTPUT).unwrap())
            .is_err()
    );
}

/// The route tick's own build gives its row to its backend's column,
/// nothing else (not its own, larger, analytic tick); a build lacking it,
/// or a main build that measured it itself, is an error.
#[test]
fn the_route_tick_build_gives_its_row() {
    let route_output = OUTPUT.replace(
        "stack robot_tick bytes=776\n",
        "stack robot_tick bytes=9999\n\
         bench robot_tick_route mean=3246.0 median=3240 min=3100 max=3500 n=100\n",
    );
    let route = parse(&route_output).unwrap();
    let mut r = parse(OUTPUT).unwrap();
    r.take_route_tick(&route).unwrap();
    assert_eq!(r.stat("robot_tick_route").map(|s| s.max), Some(3_500));
    assert_eq!(r.tick_stack_bytes, 776, "the main build's own tick");
    assert!(r.take_route_tick(&route).is_err(), "measured twice");
    assert!(
        parse(OUTPUT)
            .unwrap()
            .take_route_tick(&parse(OUTPUT).unwrap())
            .is_err()
    );
}

#[test]
fn the_docs_page_has_the_markers() {
    // `--write` fails without them; find out here, not after a bench run.
    assert!(marked_section(DOCS_PAGE, DOCS_START, DOCS_END).is_some());
}

#[test]
fn refuses_incomplete_or_failed_runs() {
    assert!(parse(&OUTPUT.replace("done\n", "")).is_err());
    assert!(parse("wmr-bench backend=libm samples=1\nerror SysTick\n").is_err());
}
