//! Position sources that do not go through the robot: the exact position,
//! the nearest tag, or reader + UART + core parser + tag grid, with the
//! scenario's noise and misses on the fix.

use rand::rngs::ChaCha8Rng;
use rand::{RngExt as _, SeedableRng as _};
use wmr_core::devices::{RfidCounters, RfidReader, TagLocator};
use wmr_core::geometry::Vec2;
use wmr_core::pilot::tracker::TagFix;

use crate::devices::{ReaderModelCounters, VirtualRfidReader, VirtualUart};
use crate::plant::PlantPose;
use crate::report::{MeasurementReport, RfidReport};
use crate::scenario::{MeasurementSpec, PositionSetup, Setup};
use crate::tags::{Floor, FloorTags};

/// Exact, nearest-tag, or reader + UART + core parser + tag grid.
// One instance per run: the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Debug)]
enum Source {
    Exact,
    Nearest(FloorTags),
    Reader {
        model: VirtualRfidReader,
        rfid: RfidReader<VirtualUart>,
        floor: Floor,
        unknown_tags: u32,
    },
}

impl Source {
    fn new(setup: &PositionSetup) -> Self {
        match setup {
            PositionSetup::Exact => Self::Exact,
            PositionSetup::NearestTag(floor) => Self::Nearest(*floor),
            PositionSetup::Reader(floor, config) => {
                let (model, uart) = VirtualRfidReader::new(*config, floor.clone());
                Self::Reader {
                    model,
                    rfid: RfidReader::new(uart),
                    floor: floor.clone(),
                    unknown_tags: 0,
                }
            }
        }
    }

    fn measure(&mut self, t_s: f64, pose: &PlantPose) -> Option<TagFix> {
        let position = match self {
            Self::Exact => Vec2::new(pose.x_m as f32, pose.y_m as f32),
            Self::Nearest(floor) => floor.nearest(pose.x_m, pose.y_m).position,
            Self::Reader {
                model,
                rfid,
                floor,
                unknown_tags,
            } => {
                model.update(t_s, pose);
                let id = rfid.poll()?;
                match floor.locate(id) {
                    Some(p) => p,
                    None => {
                        *unknown_tags = unknown_tags.saturating_add(1);
                        return None;
                    }
                }
            }
        };
        Some(TagFix {
            position,
            age_ticks: 0,
        })
    }

    fn floor_tags(&self) -> Option<usize> {
        match self {
            Self::Exact => None,
            Self::Nearest(f) => Some(f.len()),
            Self::Reader { floor, .. } => Some(floor.len()),
        }
    }

    fn rfid_counters(&self) -> Option<(RfidCounters, u32)> {
        match self {
            Self::Reader {
                rfid, unknown_tags, ..
            } => Some((rfid.counters(), *unknown_tags)),
            _ => None,
        }
    }

    fn report(&self) -> Option<RfidReport> {
        match self {
            Self::Reader {
                model,
                rfid,
                unknown_tags,
                ..
            } => Some(rfid_report(
                rfid.counters(),
                *unknown_tags,
                model.counters(),
            )),
            _ => None,
        }
    }
}

/// A [`Source`] with the scenario's noise and misses on its fix.
#[derive(Debug)]
pub(super) struct FixSource {
    source: Source,
    faults: Option<FixFaults>,
}

/// Gaussian noise and random misses on the fix. Every tick draws, in this
/// order, the miss and a pair of normals, fix or not, so the noise a tick
/// gets does not depend on the miss probability.
#[derive(Debug)]
struct FixFaults {
    spec: MeasurementSpec,
    rng: ChaCha8Rng,
    missed: u32,
}

impl FixSource {
    pub(super) fn new(setup: &Setup) -> Self {
        let spec = setup.measurement;
        Self {
            source: Source::new(&setup.position),
            faults: (!spec.is_clean()).then(|| FixFaults {
                spec,
                rng: ChaCha8Rng::seed_from_u64(spec.seed),
                missed: 0,
            }),
        }
    }

    pub(super) fn measure(&mut self, t_s: f64, pose: &PlantPose) -> Option<TagFix> {
        let fix = self.source.measure(t_s, pose);
        let Some(faults) = &mut self.faults else {
            return fix;
        };
        let miss = faults.rng.random::<f64>() < faults.spec.miss_probability;
        // Box–Muller: two independent standard normals.
        let radius = (-2.0 * (1.0 - faults.rng.random::<f64>()).ln()).sqrt();
        let angle = std::f64::consts::TAU * faults.rng.random::<f64>();
        let mut fix = fix?;
        if miss {
            faults.missed = faults.missed.saturating_add(1);
            return None;
        }
        let std = faults.spec.noise_std_m;
        fix.position = Vec2::new(
            fix.position.x + (std * radius * angle.cos()) as f32,
            fix.position.y + (std * radius * angle.sin()) as f32,
        );
        Some(fix)
    }

    pub(super) fn floor_tags(&self) -> Option<usize> {
        self.source.floor_tags()
    }

    /// The core reader's counters and the tags not on the floor, with a
    /// reader.
    pub(super) fn rfid_counters(&self) -> Option<(RfidCounters, u32)> {
        self.source.rfid_counters()
    }

    pub(super) fn report(&self) -> Option<RfidReport> {
        self.source.report()
    }

    pub(super) fn measurement_report(&self) -> Option<MeasurementReport> {
        self.faults.as_ref().map(|f| MeasurementReport {
            noise_std_m: f.spec.noise_std_m,
            miss_probability: f.spec.miss_probability,
            missed_fixes: f.missed,
        })
    }
}

pub(super) fn rfid_report(
    c: wmr_core::devices::RfidCounters,
    unknown_tags: u32,
    reader: ReaderModelCounters,
) -> RfidReport {
    RfidReport {
        frames_ok: c.frames_ok,
        bad_checksum: c.bad_checksum,
        malformed: c.malformed,
        bytes_outside_frames: c.bytes_outside_frames,
        read_errors: c.read_errors,
        superseded: c.superseded,
        backlogged_polls: c.backlogged_polls,
        unknown_tags,
        reader,
    }
}
