//! # Tag fixes as measurements
//! The nearest tag of a grid is not white noise: a robot at 0.1 m/s keeps
//! reading the same tag for a second, and an EKF fed each read as
//! independent would collapse onto the tag's centre. What does carry
//! information is the moment the nearest tag changes: the robot has just
//! crossed the boundary halfway between the two tags, along the axis that
//! changed, within the distance it drove during that tick. So the first
//! fix is a weak 2-D measurement (the uniform cell, variance `s²/12` per
//! axis) and each later change of tag is a sharp 1-D measurement of the
//! crossed axis. Reads of the same tag say the robot is still inside that
//! cell; they are skipped while the estimate is within
//! [`STRAY_ESTIMATE_GAP_M`] of it (below).
//!
//! # Stray estimates
//! Between changes of tag nothing corrects the estimate, and under wheel
//! slip it drifts: an estimate more than [`STRAY_ESTIMATE_GAP_M`] (2 cm)
//! beyond the cell of the tag still being read is wrong by at least that
//! much. Such a read truncates the estimate to the cell, along each axis
//! it has left ([`crate::estimation::fusion::truncation`]: the truncated
//! Gaussian's mean and variance, as the scalar measurement whose update
//! gives them; Simon & Simon 2010), the cell moved on by the fix's age.
//! Each is counted ([`TagCellTracker::edge_corrections`]). Closer in, the
//! read is left alone: there the estimate's own error is within what the
//! next crossing corrects, and pulling it at every read makes the filter
//! trust its position more than the reads justify. Then the correlation
//! carries each pull into the heading: 1 cm (on the template's
//! figure-eight, 32 starts) doubled the 90th percentile of the worst
//! error. The particle filter's cloud obeys the same 2 cm
//! ([`crate::estimation::fusion::particle`], "Stray clouds").
//!
//! The edge constraint ([`TagCellTracker::with_edge_constraint`]) instead
//! pulls any estimate outside the cell back to its edge, at a variance of
//! `(s/10)²` per read: the tuning for wheels that slip, with a wheel noise
//! near theirs (docs/fusion.md, "Random slip").
//!
//! A particle filter can take the read as what it is instead, the cell
//! itself ([`TagCellTracker::cell`], [`TagCell`]), on every read: see
//! [`crate::estimation::fusion::particle`].
//!
//! # The fix's age
//! A fix reaches the tick some time after the reader read the tag: the
//! reader's processing, the frame's time on its UART and the wait for the
//! tick's poll ([`TagCellTracker::with_fix_age_ticks`], in control
//! periods; the simulator's reader reads at a tick and is polled at the
//! next, one period). The robot has driven on meanwhile, at the speed of
//! the last tick, so every measurement is moved that far along the last
//! tick's displacement: a crossing is `age + ½` ticks of travel behind
//! the robot instead of `½`, a range reader's entry point `age` ticks, a
//! cell `age` ticks. Unmodelled, the age is a bias along the motion of a
//! tick's travel per period of age (5 mm at 0.5 m/s and 10 ms), which the
//! filters take for a heading error wherever the robot turns.

use crate::estimation::fusion::gate::{PI_SQUARED, PositionMeasurement};
use crate::estimation::fusion::truncation::truncation_measurement;
use crate::geometry::Vec2;
use crate::math;

/// The variance of a range reader's entry point along the heading, in
/// units of `r²`: `2/3 − π²/16` (docs of
/// [`TagCellTracker::range_measurement`]).
const ENTRY_ALONG_VARIANCE: f32 = 2.0 / 3.0 - PI_SQUARED / 16.0;

/// How far beyond the cell of the tag still being read an estimate must be
/// before the read truncates it (module docs, "Stray estimates"), m.
pub const STRAY_ESTIMATE_GAP_M: f32 = 0.02;

/// The softening of a cell's edges, m ([`TagCellTracker::cell`]).
const CELL_EDGE_STD_M: f32 = 1e-3;

/// Turns nearest-tag fixes on a square grid into the measurements they
/// carry (module docs): the first fix as the uniform cell, then each change
/// of tag as the crossing of the boundary between the two tags.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TagCellTracker {
    spacing_m: f32,
    last_tag: Option<Vec2>,
    same_tag_reads: u32,
    edge_corrections: u32,
    edges: bool,
    fix_age_ticks: f32,
}

/// A nearest-tag read as what it says exactly: the robot was in the read
/// tag's cell, the square of half-width `half_width_m` around `centre`
/// (the tag's Voronoi cell on a square grid), at some point of the last
/// tick's displacement `sweep` (the read may be up to a tick old: a frame
/// over the UART reaches the robot a tick after it was read), to within
/// `edge_std_m` at the edges ([`TagCellTracker::cell`]; the particle
/// filter's likelihood, [`crate::estimation::fusion::particle`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TagCell {
    /// The read tag, m.
    pub centre: Vec2,
    /// Half the tag spacing, m.
    pub half_width_m: f32,
    /// The robot's displacement during the last tick, m.
    pub sweep: Vec2,
    /// How far the robot drove since the read, m (the fix's age times
    /// `sweep`; [`TagCellTracker::with_fix_age_ticks`]).
    pub lag: Vec2,
    /// The softening of the cell's edges, m (> 0).
    pub edge_std_m: f32,
}

/// The span `[value − max(sweep, 0), value − min(sweep, 0)]` a coordinate
/// covered during a tick that moved it by `sweep` and ended at `value`.
fn swept_span(value: f32, sweep: f32) -> (f32, f32) {
    if sweep > 0.0 {
        (value - sweep, value)
    } else {
        (value, value - sweep)
    }
}

impl TagCell {
    /// Twice the cell's negative log-likelihood at the position `(x, y)`
    /// now (nats, up to a constant): per axis, the gap `g` between the
    /// cell and the span `[p − lag − max(sweep, 0), p − lag − min(sweep, 0)]`
    /// the robot covered during the tick of the read, `Σ_axis (max(g, 0)/σ_e)²`: 0 if the span
    /// meets the cell, a Gaussian tail of `σ_e` outside it. NaN for a
    /// non-finite position (the filter gives such a particle no weight).
    #[must_use]
    pub fn distance_sq(&self, x: f32, y: f32) -> f32 {
        let h = self.half_width_m;
        let outside = |value: f32, centre: f32, sweep: f32| {
            let (low, high) = swept_span(value, sweep);
            let gap = (low - (centre + h)).max((centre - h) - high);
            // NaN stays NaN (`max` drops one NaN, not two).
            if gap > 0.0 || gap.is_nan() {
                gap / self.edge_std_m
            } else {
                0.0
            }
        };
        let dx = outside(x - self.lag.x, self.centre.x, self.sweep.x);
        let dy = outside(y - self.lag.y, self.centre.y, self.sweep.y);
        dx * dx + dy * dy
    }

    /// The shortest move of the position `(x, y)` that makes the span of
    /// [`Self::distance_sq`] meet the cell, per axis, m: the gap to the
    /// nearer edge, towards the cell, on an axis where the span misses it;
    /// 0 where it meets it. After the move `distance_sq` is 0 but for
    /// rounding. NaN for a non-finite position.
    #[must_use]
    pub fn shift_onto(&self, x: f32, y: f32) -> Vec2 {
        let h = self.half_width_m;
        let shift = |value: f32, centre: f32, sweep: f32| {
            let (low, high) = swept_span(value, sweep);
            if !(low.is_finite() && high.is_finite()) {
                f32::NAN
            } else if low > centre + h {
                (centre + h) - low
            } else if high < centre - h {
                (centre - h) - high
            } else {
                0.0
            }
        };
        Vec2::new(
            shift(x - self.lag.x, self.centre.x, self.sweep.x),
            shift(y - self.lag.y, self.centre.y, self.sweep.y),
        )
    }

    /// The cell as a Gaussian of the same moments, centred half the sweep
    /// and the lag ahead of the tag with variance `h²/3 + sweep²/12 + σ_e²` per axis
    /// (the uniform square's `(2h)²/12`, the sweep's uniform share): what
    /// the gate and the re-localisation of
    /// [`crate::estimation::fusion::gate`] take.
    #[must_use]
    pub fn moments(&self) -> PositionMeasurement {
        let h = self.half_width_m;
        let e2 = self.edge_std_m * self.edge_std_m;
        let (sx, sy) = (self.sweep.x, self.sweep.y);
        PositionMeasurement::Point {
            position: Vec2::new(
                self.centre.x + self.lag.x + 0.5 * sx,
                self.centre.y + self.lag.y + 0.5 * sy,
            ),
            variance_m2: [
                h * h / 3.0 + sx * sx / 12.0 + e2,
                h * h / 3.0 + sy * sy / 12.0 + e2,
            ],
        }
    }
}

/// What a fix told the tracker ([`TagCellTracker::measurements`]): the kind
/// of the measurements it gave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CellReading {
    /// A non-finite tag, step or estimate: no measurement, and the tracker
    /// is unchanged.
    Invalid,
    /// The first fix: the tag's uniform cell, a weak 2-D measurement.
    First,
    /// An unchanged tag: no measurement, or a stray estimate's truncation
    /// or the edge constraint's pull, one per axis left (module docs).
    SameTag,
    /// A change to an adjacent tag: the crossing of the boundary between
    /// the two, a sharp 1-D measurement per axis crossed.
    Crossing,
    /// A jump past a neighbour: the tag's uniform cell, a weak 2-D
    /// measurement.
    Jump,
}

/// How a read's tag relates to the last read tag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TagChange {
    /// The same tag (within half a spacing on both axes).
    Same,
    /// A neighbour: one or both boundaries crossed.
    Adjacent,
    /// Past a neighbour on some axis.
    Jump,
}

/// The measurements of one fix (at most two: both axes crossed or left at
/// once) and what kind they are.
#[derive(Debug, Clone, PartialEq)]
pub struct CellMeasurements {
    reading: CellReading,
    measurements: heapless::Vec<PositionMeasurement, 2>,
}

impl CellMeasurements {
    const fn new(reading: CellReading) -> Self {
        Self {
            reading,
            measurements: heapless::Vec::new(),
        }
    }

    /// One measurement of the given kind.
    fn one(reading: CellReading, measurement: PositionMeasurement) -> Self {
        let mut out = Self::new(reading);
        // Capacity 2: the first push cannot fail.
        let _ = out.measurements.push(measurement);
        out
    }

    /// What kind of fix gave these measurements.
    #[must_use]
    pub fn reading(&self) -> CellReading {
        self.reading
    }

    /// The measurements, in the order the filter takes them.
    #[must_use]
    pub fn as_slice(&self) -> &[PositionMeasurement] {
        &self.measurements
    }
}

impl<'a> IntoIterator for &'a CellMeasurements {
    type Item = &'a PositionMeasurement;
    type IntoIter = core::slice::Iter<'a, PositionMeasurement>;

    /// By reference: the slice iterator has no bounds check (the by-value
    /// iterator of heapless's `Vec` indexes, with a panic path).
    fn into_iter(self) -> Self::IntoIter {
        self.measurements.iter()
    }
}

impl TagCellTracker {
    /// For a grid of this spacing (m); `None` unless finite and positive.
    #[must_use]
    pub fn new(spacing_m: f32) -> Option<Self> {
        (spacing_m.is_finite() && spacing_m > 0.0).then_some(Self {
            spacing_m,
            last_tag: None,
            same_tag_reads: 0,
            edge_corrections: 0,
            edges: false,
            fix_age_ticks: 0.0,
        })
    }

    /// For a spacing and a fix age already validated (finite, the spacing
    /// positive, the age ≥ 0), with the edge constraint on or off.
    pub(super) fn with_validated(spacing_m: f32, edges: bool, fix_age_ticks: f32) -> Self {
        Self {
            spacing_m,
            last_tag: None,
            same_tag_reads: 0,
            edge_corrections: 0,
            edges,
            fix_age_ticks,
        }
    }

    /// The age of each fix when its tick runs, in control periods (module
    /// docs, "The fix's age"; default 0); `None` unless finite and ≥ 0.
    #[must_use]
    pub fn with_fix_age_ticks(self, fix_age_ticks: f32) -> Option<Self> {
        (fix_age_ticks.is_finite() && fix_age_ticks >= 0.0).then_some(Self {
            fix_age_ticks,
            ..self
        })
    }

    /// Whether reads of an unchanged tag pull an estimate that has left its
    /// cell back to the edge, however little (default off: only a stray
    /// estimate is truncated, module docs. On the figure-eight the edge
    /// constraint halves the worst error under wheel slip but triples it
    /// without, because the edge "measurement" is made from the estimate
    /// itself and its correlation leaks into the heading).
    #[must_use]
    pub fn with_edge_constraint(self, edges: bool) -> Self {
        Self { edges, ..self }
    }

    /// Reads of an unchanged tag (they carry information only when the
    /// estimate has left the tag's cell).
    #[must_use]
    pub fn same_tag_reads(&self) -> u32 {
        self.same_tag_reads
    }

    /// Edge measurements made because the estimate had left the cell of the
    /// tag still being read: a stray estimate's truncations (module docs),
    /// or the edge constraint's pulls.
    #[must_use]
    pub fn edge_corrections(&self) -> u32 {
        self.edge_corrections
    }

    /// Forgets the last tag (after a gap in the reads, when a change of tag
    /// need not mean one boundary crossed during the last tick).
    pub fn restart(&mut self) {
        self.last_tag = None;
    }

    /// The measurement of a read of `tag` by a reader of range `radius_m`
    /// ([`crate::estimation::fusion::FusionSettings::with_read_radius`]) on a robot heading `heading`
    /// (rad), `travel_m` driven since the last read, `step_m` during the
    /// last tick (along the heading: the entry point is moved on by the
    /// fix's age times that step, module docs): the first read of each
    /// pass (a different tag, or the same one after more than `2r` driven:
    /// a range reader repeats its read while the tag stays in range, so a
    /// gap in the reads alone does not end a pass) is where the antenna
    /// entered the disc around the tag.
    /// At a lateral offset `d` (uniform in `[−r, r]`) that is `√(r² − d²)`
    /// short of the tag along the heading: mean `πr/4` short, lateral
    /// variance `r²/3`, along-track variance `(2/3 − π²/16) r² ≈ 0.05 r²`.
    /// The measurement is the tag moved back by `πr/4` along the heading,
    /// with those variances along and across the heading
    /// ([`PositionMeasurement::Ellipse`]). Repeats within a pass give
    /// nothing (counted).
    pub fn range_measurement(
        &mut self,
        tag: Vec2,
        heading: f32,
        travel_m: f32,
        radius_m: f32,
        step_m: f32,
    ) -> Option<PositionMeasurement> {
        if !(tag.is_finite() && heading.is_finite() && step_m.is_finite()) {
            return None;
        }
        if self.last_tag.replace(tag) == Some(tag) && travel_m <= 2.0 * radius_m {
            self.same_tag_reads = self.same_tag_reads.saturating_add(1);
            return None;
        }
        let back = core::f32::consts::FRAC_PI_4 * radius_m;
        let r2 = radius_m * radius_m;
        let (along, across) = (ENTRY_ALONG_VARIANCE * r2, r2 / 3.0);
        let (s, c) = math::sincos(heading);
        let lag = Vec2::new(c, s).scaled(step_m * self.fix_age_ticks);
        Some(PositionMeasurement::Ellipse {
            position: Vec2::new(tag.x - back * c + lag.x, tag.y - back * s + lag.y),
            // R(θ) diag(along, across) R(θ)ᵀ.
            covariance_m2: [
                along * c * c + across * s * s,
                (along - across) * c * s,
                along * s * s + across * c * c,
            ],
        })
    }

    /// A read of `tag` as its cell ([`TagCell`]), the robot having moved
    /// by `last_step` during the last tick (from odometry and the current
    /// heading estimate, as for [`Self::measurements`]; at most a spacing
    /// per axis), the edges softened by 1 mm (the reader's own position
    /// error, as for a crossing in [`Self::measurements`]). Every read
    /// gives one, an unchanged tag included (counted as a same-tag read):
    /// for a particle filter "still in this cell" is information. `None`
    /// for a non-finite tag or step.
    pub fn cell(&mut self, tag: Vec2, last_step: Vec2) -> Option<TagCell> {
        if !(tag.is_finite() && last_step.is_finite()) {
            return None;
        }
        let s = self.spacing_m;
        if let Some(last) = self.last_tag.replace(tag)
            && (tag.x - last.x).abs() <= 0.5 * s
            && (tag.y - last.y).abs() <= 0.5 * s
        {
            self.same_tag_reads = self.same_tag_reads.saturating_add(1);
        }
        let sweep = self.clamped_step(last_step);
        Some(TagCell {
            centre: tag,
            half_width_m: 0.5 * s,
            sweep,
            lag: sweep.scaled(self.fix_age_ticks),
            edge_std_m: CELL_EDGE_STD_M,
        })
    }

    /// The last tick's displacement with each axis clamped to one spacing
    /// (a larger step is not a tick's travel between reads of one grid).
    fn clamped_step(&self, last_step: Vec2) -> Vec2 {
        let s = self.spacing_m;
        // `max`/`min`, not `clamp`: `clamp` has a panic path (for bounds
        // the optimiser cannot prove ordered), which the release firmware
        // must not link.
        Vec2::new(last_step.x.max(-s).min(s), last_step.y.max(-s).min(s))
    }

    /// The measurements of a fix at `tag`, given the displacement `(Δx, Δy)`
    /// the robot made during the last tick (from odometry and the current
    /// heading estimate), the current position estimate and the source of
    /// its variances `[σx², σy²]` (m²; called only for a stray estimate's
    /// truncation, so that a filter assembles its covariance only then).
    pub fn measurements(
        &mut self,
        tag: Vec2,
        last_step: Vec2,
        estimate: Vec2,
        variance_m2: impl FnOnce() -> [f32; 2],
    ) -> CellMeasurements {
        if !(tag.is_finite() && last_step.is_finite() && estimate.is_finite()) {
            return CellMeasurements::new(CellReading::Invalid);
        }
        let s = self.spacing_m;
        let cell = s * s / 12.0;
        let Some(last) = self.last_tag.replace(tag) else {
            return CellMeasurements::one(
                CellReading::First,
                PositionMeasurement::Point {
                    position: tag,
                    variance_m2: [cell, cell],
                },
            );
        };
        let change = self.tag_change(last, tag);
        if change == TagChange::Same {
            // Still in the same cell: an estimate that has left it is pulled
            // back (module docs, "Stray estimates" and the edge constraint).
            self.same_tag_reads = self.same_tag_reads.saturating_add(1);
            let mut out = CellMeasurements::new(CellReading::SameTag);
            let edge = |estimate: f32, centre: f32| {
                let offset = estimate - centre;
                (offset.abs() > 0.5 * s).then(|| centre + 0.5 * s * offset.signum())
            };
            let edge_variance = s * s / 100.0;
            let (x, y) = if self.edges {
                (
                    edge(estimate.x, tag.x).map(|value_m| (value_m, edge_variance)),
                    edge(estimate.y, tag.y).map(|value_m| (value_m, edge_variance)),
                )
            } else {
                // Where the cell read `age` ticks ago now is, along the
                // motion.
                let centre = tag + self.clamped_step(last_step).scaled(self.fix_age_ticks);
                let within_gap = |estimate: f32, centre: f32| {
                    estimate >= centre - 0.5 * s - STRAY_ESTIMATE_GAP_M
                        && estimate <= centre + 0.5 * s + STRAY_ESTIMATE_GAP_M
                };
                let (x_within, y_within) = (
                    within_gap(estimate.x, centre.x),
                    within_gap(estimate.y, centre.y),
                );
                if x_within && y_within {
                    return out;
                }
                let [variance_x, variance_y] = variance_m2();
                let stray = |within: bool, estimate: f32, variance: f32, centre: f32| {
                    if within {
                        return None;
                    }
                    truncation_measurement(estimate, variance, centre - 0.5 * s, centre + 0.5 * s)
                };
                (
                    stray(x_within, estimate.x, variance_x, centre.x),
                    stray(y_within, estimate.y, variance_y, centre.y),
                )
            };
            if let Some((value_m, variance_m2)) = x {
                let _ = out.measurements.push(PositionMeasurement::X {
                    value_m,
                    variance_m2,
                });
                self.edge_corrections = self.edge_corrections.saturating_add(1);
            }
            if let Some((value_m, variance_m2)) = y {
                let _ = out.measurements.push(PositionMeasurement::Y {
                    value_m,
                    variance_m2,
                });
                self.edge_corrections = self.edge_corrections.saturating_add(1);
            }
            return out;
        }
        if change == TagChange::Jump {
            // A jump past a neighbour: not one boundary crossed; weak fix.
            return CellMeasurements::one(
                CellReading::Jump,
                PositionMeasurement::Point {
                    position: tag,
                    variance_m2: [cell, cell],
                },
            );
        }
        self.crossings(last, tag, last_step)
    }

    /// The crossing a read of `tag` would be, without taking the read
    /// (the tracker is unchanged): `None` unless the read changes to an
    /// adjacent tag, or for a non-finite tag or step. For a particle
    /// filter, which takes every read as its cell ([`Self::cell`]) but
    /// adapts its wheel noise from the crossings' innovations as the other
    /// filters do ([`crate::estimation::fusion::noise_adaptation`]).
    #[must_use]
    pub fn crossing(&self, tag: Vec2, last_step: Vec2) -> Option<CellMeasurements> {
        if !(tag.is_finite() && last_step.is_finite()) {
            return None;
        }
        let last = self.last_tag?;
        (self.tag_change(last, tag) == TagChange::Adjacent)
            .then(|| self.crossings(last, tag, last_step))
    }

    /// Whether tags `d` apart along an axis lie in different cells: the
    /// boundary halfway between them crossed.
    fn crossed(&self, d: f32) -> bool {
        d.abs() > 0.5 * self.spacing_m
    }

    /// How a read of `tag` relates to the last read tag `last`.
    fn tag_change(&self, last: Vec2, tag: Vec2) -> TagChange {
        let (dx, dy) = (tag.x - last.x, tag.y - last.y);
        let adjacent = |d: f32| d.abs() < 1.5 * self.spacing_m;
        if !self.crossed(dx) && !self.crossed(dy) {
            TagChange::Same
        } else if adjacent(dx) && adjacent(dy) {
            TagChange::Adjacent
        } else {
            TagChange::Jump
        }
    }

    /// The measurements of a change from `last` to the adjacent `tag`: the
    /// crossing of each boundary between them (module docs).
    fn crossings(&self, last: Vec2, tag: Vec2, last_step: Vec2) -> CellMeasurements {
        let s = self.spacing_m;
        let (dx, dy) = (tag.x - last.x, tag.y - last.y);
        // The robot crossed the boundary during the tick of the read and is
        // now beyond it by a uniform fraction of that tick's travel, plus
        // the travel of the fix's age (module docs).
        let beyond = 0.5 + self.fix_age_ticks;
        let crossing = |from: f32, to: f32, step: f32| {
            let boundary = 0.5 * (from + to);
            let travel = step.abs().min(s);
            let value = boundary + (to - from).signum() * beyond * travel;
            // Travel²/12, plus 1 mm² for the reader's own position error.
            (value, travel * travel / 12.0 + 1e-6)
        };
        let mut out = CellMeasurements::new(CellReading::Crossing);
        if self.crossed(dx) {
            let (value_m, variance_m2) = crossing(last.x, tag.x, last_step.x);
            let _ = out.measurements.push(PositionMeasurement::X {
                value_m,
                variance_m2,
            });
        }
        if self.crossed(dy) {
            let (value_m, variance_m2) = crossing(last.y, tag.y, last_step.y);
            let _ = out.measurements.push(PositionMeasurement::Y {
                value_m,
                variance_m2,
            });
        }
        out
    }
}
