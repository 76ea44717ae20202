//! The specs' `Arbitrary` implementations (core feature `arbitrary`),
//! which the fuzz targets draw their pilots from: a short input is a
//! valid spec, and the draws reach every estimator, filter and law.

use arbitrary::Unstructured;
use wmr_core::devices::tag_grid::TagGridSpec;
use wmr_core::pilot::spec::PilotSpec;

#[test]
fn an_empty_input_draws_typical_specs_that_build() {
    let mut u = Unstructured::new(&[]);
    let pilot: PilotSpec = u.arbitrary().unwrap();
    assert_eq!(pilot.build().map(|_| ()), Ok(()));
    let grid: TagGridSpec = u.arbitrary().unwrap();
    assert!(grid.build().is_ok());
}

/// The variant's name in a spec's `Debug` form (`Fusion(FusionSpec { filter:
/// Ukf, .. })` is the fusion estimator on `Ukf`), so that no list of the
/// estimators and laws is kept here.
fn arm(debug: &str) -> String {
    let name: String = debug.chars().take_while(|c| c.is_alphanumeric()).collect();
    match debug.split("filter: ").nth(1) {
        Some(filter) => {
            let filter: String = filter.chars().take_while(|c| c.is_alphanumeric()).collect();
            format!("{name} {filter}")
        }
        None => name,
    }
}

#[test]
fn the_draws_reach_every_estimator_filter_and_law() {
    use std::collections::BTreeMap;
    // xorshift bytes: reproducible inputs of 256 bytes each.
    let mut state = 0x2545_F491_4F6C_DD1D_u64;
    // arm -> (drawn, built)
    let mut arms: BTreeMap<String, (u32, u32)> = BTreeMap::new();
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
        let built = u32::from(spec.build().is_ok());
        for name in [
            format!(
                "estimator {}",
                arm(&format!("{:?}", spec.tracker.estimator))
            ),
            format!("law {}", arm(&format!("{:?}", spec.tracker.law))),
        ] {
            let entry = arms.entry(name).or_default();
            entry.0 += 1;
            entry.1 += built;
        }
    }
    println!("{arms:#?}");
    // Today's 3 estimators (the fusion one on 3 filters) and 3 laws.
    let count = |kind: &str| arms.keys().filter(|k| k.starts_with(kind)).count();
    assert!(count("estimator ") >= 5 && count("law ") >= 3, "{arms:?}");
    // Every arm drawn is drawn with some specs that build, so that the
    // fuzz targets reach its control loop as well as its refusals.
    assert!(arms.values().all(|&(_, built)| built > 0), "{arms:?}");
}
