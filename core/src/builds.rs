//! The optional builds of the estimator layer, listed once: the cargo
//! features that add an estimator or a drive observer to the firmware
//! (each of the same name in `wmr-core` and `wmr-firmware`; both boards
//! carry the fusion EKF, `fusion-ekf`, without asking).
//!
//! What reads this list: `cargo xtask` (the panic-free proof builds each
//! alone, `ci` builds each QEMU-board firmware for the HIL tests, the
//! bench's particle-filter rows build theirs), the HIL tests (which find
//! each firmware by [`OptionalBuild::hil_firmware_env`]) and
//! `firmware-sim` (the builds a robot's spec needs:
//! [`crate::pilot::spec::PilotSpec::required_builds`], from each layer's
//! [`crate::estimation::spec::EstimatorSpec::required_build`] and
//! [`crate::drive::spec::DriveSpec::required_build`]). A new optional
//! estimator adds its feature to both manifests, its entry here and its
//! arm in its layer's `required_build`.

/// An optional build: a cargo feature and what names it in file names and
/// the environment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OptionalBuild {
    /// The cargo feature of `wmr-core` and of `wmr-firmware`.
    pub feature: &'static str,
    /// What the feature adds, for people.
    pub adds: &'static str,
    /// The environment variable that gives the HIL tests this build's
    /// QEMU-board firmware ELF (`cargo xtask ci` builds it and sets it).
    pub hil_firmware_env: &'static str,
}

/// Paper 004's UKF as the fusion estimator's filter.
pub const FUSION_UKF: OptionalBuild = OptionalBuild {
    feature: "fusion-ukf",
    adds: "the fusion estimator's UKF",
    hil_firmware_env: "WMR_FIRMWARE_ELF_FUSION_UKF",
};

/// Paper 004's particle filter as the fusion estimator's filter.
pub const FUSION_PARTICLE_FILTER: OptionalBuild = OptionalBuild {
    feature: "fusion-particle-filter",
    adds: "the fusion estimator's particle filter",
    hil_firmware_env: "WMR_FIRMWARE_ELF_FUSION_PARTICLE_FILTER",
};

/// Paper 003's wheel-speed observer in the drive's speed loops.
pub const WHEEL_SPEED_OBSERVER: OptionalBuild = OptionalBuild {
    feature: "wheel-speed-observer",
    adds: "paper 003's wheel-speed observer in the speed loops",
    hil_firmware_env: "WMR_FIRMWARE_ELF_WHEEL_SPEED_OBSERVER",
};

/// Every optional build.
pub const OPTIONAL_BUILDS: [OptionalBuild; 3] =
    [FUSION_UKF, FUSION_PARTICLE_FILTER, WHEEL_SPEED_OBSERVER];

#[cfg(test)]
mod tests {
    use super::OPTIONAL_BUILDS;

    /// Each build's environment variable is its feature in capitals.
    #[test]
    fn each_build_names_its_firmware_by_its_feature() {
        for build in OPTIONAL_BUILDS {
            let expected = std::format!(
                "WMR_FIRMWARE_ELF_{}",
                build.feature.to_uppercase().replace('-', "_")
            );
            assert_eq!(build.hil_firmware_env, expected);
        }
    }
}
