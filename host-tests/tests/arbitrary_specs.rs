//! The specs' `Arbitrary` implementations (core feature `arbitrary`),
//! which the fuzz targets draw their pilots from: a short input is a
//! valid spec, and the draws reach every estimator, filter and law.

use arbitrary::Unstructured;
use wmr_core::control::spec::LawSpec;
use wmr_core::devices::tag_grid::TagGridSpec;
use wmr_core::estimation::spec::{EstimatorSpec, FusionFilterSpec};
use wmr_core::pilot::spec::PilotSpec;

#[test]
fn an_empty_input_draws_typical_specs_that_build() {
    let mut u = Unstructured::new(&[]);
    let pilot: PilotSpec = u.arbitrary().unwrap();
    assert_eq!(pilot.build().map(|_| ()), Ok(()));
    let grid: TagGridSpec = u.arbitrary().unwrap();
    assert!(grid.build().is_ok());
}

#[test]
fn the_draws_reach_every_estimator_filter_and_law() {
    // xorshift bytes: reproducible inputs of 256 bytes each.
    let mut state = 0x2545_F491_4F6C_DD1D_u64;
    let mut drawn = [0_u32; 8];
    let mut built = [0_u32; 8];
    for _ in 0..20_000 {
        let bytes: Vec<u8> = (0..256)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 24) as u8
            })
            .collect();
        let spec: PilotSpec = Unstructured::new(&bytes).arbitrary().unwrap();
        let estimator = match spec.tracker.estimator {
            EstimatorSpec::HeadingObserver => 0,
            EstimatorSpec::PoseObserver { .. } => 1,
            EstimatorSpec::Fusion(f) => match f.filter {
                FusionFilterSpec::Ekf => 2,
                FusionFilterSpec::Ukf => 3,
                FusionFilterSpec::ParticleFilter => 4,
            },
        };
        let law = match spec.tracker.law {
            LawSpec::Saturated => 5,
            LawSpec::Cascaded { .. } => 6,
            LawSpec::HeadingErrorSine { .. } => 7,
        };
        let ok = u32::from(spec.build().is_ok());
        for arm in [estimator, law] {
            drawn[arm] += 1;
            built[arm] += ok;
        }
    }
    println!("drawn {drawn:?}\nbuilt {built:?}");
    // Every arm is drawn, and with some draws that build, so that the
    // fuzz targets reach its control loop as well as its refusals.
    assert!(built.iter().all(|&b| b > 0), "estimators 0-4, laws 5-7");
}
