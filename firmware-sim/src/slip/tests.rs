//! The slip scenario's defaults, files and validation.

use super::*;
use wmr_papers::slip_tracking::{PiecewiseReference, SlipGains, TrackedRobot};

fn minimal(controller: &str) -> SlipScenario {
    SlipScenario::from_toml_str(&format!("name = \"m\"\ncontroller = \"{controller}\"\n")).unwrap()
}

#[test]
fn defaults_are_the_papers_constants() {
    let s = minimal("velocity");
    let r = &s.robot;
    let robot = TrackedRobot::new(
        r.wheel_radius_m as f32,
        r.track_width_m as f32,
        r.mass_kg as f32,
        r.yaw_inertia_kg_m2 as f32,
    )
    .unwrap();
    assert_eq!(robot, TrackedRobot::PAPER);
    let g = &s.gains;
    let gains = SlipGains::new(
        g.k1 as f32,
        g.k2 as f32,
        g.k3 as f32,
        g.k4 as f32,
        g.k5 as f32,
        g.rho as f32,
    )
    .unwrap();
    assert_eq!(gains, SlipGains::PAPER);
    assert_eq!(
        s.filter.particle_filter.process_std.map(|x| x as f32),
        PARTICLE_PROCESS_STD
    );
    let ours = s.reference_sampler().unwrap();
    let paper = PiecewiseReference::<4>::paper().unwrap();
    for k in 0..=1300 {
        let t = k as f32 * 0.05;
        assert_eq!(ours(t), paper.sample(t), "{t}");
    }
    for k in 0..12_000 {
        let t = f64::from(k) * PERIOD_S;
        let paper = if (SLIP_WINDOW_S.0..SLIP_WINDOW_S.1).contains(&t) {
            SLIP_RATIO
        } else {
            0.0
        };
        assert_eq!(slip_ratio(t), paper, "{t}");
    }
}

#[test]
fn the_embedded_files_are_the_defaults_with_the_papers_initial_states() {
    for (name, controller) in [
        ("paper_004_velocity", Controller::Velocity),
        ("paper_004_torque", Controller::Torque),
    ] {
        let file = SlipScenario::embedded(name).unwrap();
        let mut defaults = minimal(controller.name());
        defaults.name = file.name.clone();
        defaults.description = file.description.clone();
        defaults.initial = Some(InitialState::paper(controller));
        assert_eq!(file, defaults, "{name}");
        let toml = file.to_toml_string().unwrap();
        assert_eq!(SlipScenario::from_toml_str(&toml).unwrap(), file, "{toml}");
    }
}

#[test]
fn a_minimal_file_runs_the_same_as_the_embedded_one() {
    let mut a = SlipScenario::embedded("paper_004_torque").unwrap();
    let mut b = minimal("torque");
    for s in [&mut a, &mut b] {
        s.duration_s = 3.0;
        s.name = "x".into();
        s.description.clear();
    }
    assert_eq!(run(&a).unwrap().records, run(&b).unwrap().records);
}

#[test]
fn more_reference_segments_than_the_limit_are_refused() {
    let mut s = minimal("velocity");
    s.reference.segments = (0..=MAX_SEGMENTS)
        .map(|k| SegmentSpec {
            start_s: k as f64,
            v_m_s: 0.5,
            omega_rad_s: 0.0,
        })
        .collect();
    let e = s.validate().unwrap_err();
    assert_eq!(e.field(), Some("reference.segments"), "{e}");
    s.reference.segments.truncate(2);
    s.validate().unwrap();
    s.reference.segments[1].start_s = 0.0;
    let e = s.validate().unwrap_err();
    assert_eq!(e.field(), Some("reference.segments[1].start_s"), "{e}");
}

/// Each built-in particle count runs (a short run, both scenarios) and
/// gives its own particles: the estimates differ between counts, and the
/// default is the paper's 100.
#[test]
fn every_built_in_particle_count_runs() {
    assert_eq!(PARTICLES, 100);
    for controller in ["velocity", "torque"] {
        let mut estimates = Vec::new();
        for count in PARTICLE_COUNTS {
            let mut s = minimal(controller);
            s.estimator = Estimator::ParticleFilter;
            s.duration_s = 1.0;
            s.filter.particle_filter.particles = count;
            s.validate().unwrap();
            let result = run(&s).unwrap();
            assert_eq!(result.summary.non_finite_records, 0, "{controller} {count}");
            estimates.push(result.records.last().map(|r| r.estimate_error_m).unwrap());
        }
        assert!(
            estimates.windows(2).all(|w| w[0] != w[1]),
            "{controller}: {estimates:?}"
        );
    }
}
