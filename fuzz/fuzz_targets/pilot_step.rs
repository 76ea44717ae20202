//! An arbitrary `PilotSpec` (every estimator and law; NaN, ±∞, huge and
//! zero values among typical ones) into `PilotSpec::build`; when it builds,
//! `Pilot::step` over an arbitrary run of measurements (encoder counters
//! that move, jump, wrap or fail; tag fixes anywhere, NaN included, of any
//! age, or none).
//!
//! Every tick: both duties finite and in [-1, 1] (the drive's signed ones
//! and the motor commands); the command finite; an encoder halt stops both
//! motors; no fix yet means no command; in the failsafe the command only
//! shrinks; the wheel targets within the drive's speed limit; the
//! reference finite; the answer's `fix_used` exactly when the tracker
//! counts the fix used (a fix is refused, and counted, when not finite or
//! older than `max_fix_age_ticks`).

#![no_main]

use arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use wmr_core::estimation::spec::{EstimatorSpec, FusionFilterSpec, FusionSpec};
use wmr_core::geometry::Vec2;
use wmr_core::pilot::tracker::{TagFix, TrackerMode};
use wmr_core::pilot::{Measurement, Pilot};
use wmr_fuzz::{encoder_count, float, pilot_spec};

/// Ticks per input at most: enough to reach the failsafe with a short
/// timeout, few enough that the particle filter (the slowest estimator)
/// keeps the executions per second up.
const MAX_TICKS: usize = 100;
/// Ticks per input at most with the particle filter (100 particles: ten
/// times the EKF's work per tick).
const MAX_PARTICLE_FILTER_TICKS: usize = 24;

fn fix(u: &mut Unstructured) -> Result<Option<TagFix>> {
    if !u.ratio(1, 3)? {
        return Ok(None);
    }
    let near = |u: &mut Unstructured| -> Result<f32> { Ok(f32::from(u.arbitrary::<i8>()?) * 0.05) };
    let position = if u.ratio(1, 8)? {
        Vec2::new(float(u, 1.0)?, float(u, 1.0)?)
    } else {
        Vec2::new(near(u)?, near(u)?)
    };
    let age_ticks = if u.ratio(1, 8)? {
        u.arbitrary()?
    } else {
        u.int_in_range(0..=3)?
    };
    Ok(Some(TagFix {
        position,
        age_ticks,
    }))
}

fn run(u: &mut Unstructured) -> Result<()> {
    let spec = pilot_spec(u)?;
    let Ok(config) = spec.build() else {
        return Ok(());
    };
    let mut pilot = Pilot::new(config).expect("a built configuration makes a pilot");
    let max_wheel_speed = config.drive().max_wheel_speed_rad_s();
    let max_fix_age_ticks = spec.tracker.max_fix_age_ticks;
    let (mut left, mut right) = (0_u32, 0_u32);
    let mut previous_command = None;
    let ticks = match spec.tracker.estimator {
        EstimatorSpec::Fusion(FusionSpec {
            filter: FusionFilterSpec::ParticleFilter,
            ..
        }) => MAX_PARTICLE_FILTER_TICKS,
        _ => MAX_TICKS,
    };
    for _ in 0..ticks {
        if u.is_empty() {
            break;
        }
        let left_count = encoder_count(u, left)?;
        let right_count = encoder_count(u, right)?;
        left = left_count.unwrap_or(left);
        right = right_count.unwrap_or(right);
        let m = Measurement {
            left_count,
            right_count,
            fix: fix(u)?,
        };
        let before = pilot.tracker().counters();
        let out = pilot.step(&m);
        let after = pilot.tracker().counters();

        // The answer says a fix was used exactly when the tracker counted
        // it used: never without one, never for a non-finite or stale one
        // (which the tracker counts instead).
        let used = after.fixes_used - before.fixes_used;
        let refused =
            (after.invalid_fixes - before.invalid_fixes) + (after.stale_fixes - before.stale_fixes);
        assert_eq!(u32::from(out.tracker.fix_used), used, "{m:?} {out:?}");
        match m.fix {
            None => assert_eq!((used, refused), (0, 0)),
            Some(f) => {
                let fresh = f.position.is_finite() && f.age_ticks <= max_fix_age_ticks;
                assert_eq!(out.tracker.fix_used, fresh, "{f:?}");
                assert_eq!(refused, u32::from(!fresh), "{f:?}");
            }
        }
        // A configuration that builds keeps its reference finite.
        let r = out.tracker.reference;
        assert!(
            r.position.is_finite() && r.velocity.is_finite() && r.acceleration.is_finite(),
            "{r:?}"
        );

        for duty in [out.drive.left_duty, out.drive.right_duty] {
            assert!(
                duty.is_finite() && (-1.0..=1.0).contains(&duty),
                "duty {duty}: {out:?}"
            );
        }
        for motor in [out.left, out.right] {
            assert!(
                motor.duty.is_finite() && (0.0..=1.0).contains(&motor.duty),
                "{motor:?}"
            );
            assert!((-1.0..=1.0).contains(&motor.signed()));
        }
        if out.encoder_halt {
            assert!(out.left.is_stop() && out.right.is_stop(), "halt: {out:?}");
            assert_eq!((out.drive.left_duty, out.drive.right_duty), (0.0, 0.0));
        }
        let command = out.tracker.command;
        assert!(command.is_finite(), "{out:?}");
        match out.tracker.mode {
            TrackerMode::AwaitingFix => {
                assert_eq!((command.v_m_s, command.omega_rad_s), (0.0, 0.0));
            }
            TrackerMode::FixLost => {
                if let Some((v, w)) = previous_command {
                    assert!(command.v_m_s.abs() <= v, "failsafe sped up: {out:?}");
                    assert!(
                        command.omega_rad_s.abs() <= w,
                        "failsafe turned faster: {out:?}"
                    );
                }
            }
            TrackerMode::Tracking => {}
        }
        previous_command = Some((command.v_m_s.abs(), command.omega_rad_s.abs()));
        let t = out.drive.wheel_targets;
        assert!(t.is_finite(), "{out:?}");
        // Within the limit up to rounding: the drive scales by
        // `(target / largest) * max`, whose quotient is in [-1, 1], so no
        // subnormal scale factor loses precision (corpus `overshoot-*`).
        let limit = max_wheel_speed * (1.0 + 1e-5);
        assert!(
            t.left_rad_s.abs() <= limit && t.right_rad_s.abs() <= limit,
            "wheel targets over {max_wheel_speed} rad/s: {out:?}"
        );
    }
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    let _ = run(&mut Unstructured::new(data));
});
