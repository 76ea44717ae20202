//! The pose EKF: paper 004's EKF algorithm (`core/src/filters/ekf.rs`,
//! Joseph form) on the prediction of
//! [`crate::estimation::fusion::odometry_noise`] and the correction of
//! [`crate::estimation::fusion::gate`], written for the structure of this
//! filter instead of with dense 5×5 products:
//!
//! ```text
//! predict (paper 004: x⁻ = f(x, u), P⁻ = A P Aᵀ + Q; here A = F, Q = G Σ Gᵀ + walk)
//!   F = I + five columns' worth of entries (OdometryJacobian): F P is three
//!   row updates of P, (F P) Fᵀ three column updates of F P.
//! update (paper 004: S = C P⁻ Cᵀ + R, K = P⁻ Cᵀ S⁻¹, x = x⁻ + K ỹ,
//!         P = (I − K C) P⁻ (I − K C)ᵀ + K R Kᵀ; here C = H reads x, y or both)
//!   ỹ and S are 1-D (S a scalar) or 2-D (S 2×2, inverted in closed form):
//!   H P Hᵀ is P's x/y block, P Hᵀ its x/y columns, and I − K H is the
//!   identity but for its first two columns.
//! ```
//!
//! Every product keeps the order of the dense matrix product (the
//! `k` of `Σ_k A_ik B_kj` ascending, from `A_i0 B_0j`), leaving out only
//! terms that are exactly 0 and factors that are exactly 1: the filter's
//! figures are those of the dense code to the last bit (the tests check it
//! against a dense reference), as its chaotic worst-case errors need
//! (docs/fusion.md, "One run is one sample").
//!
//! The covariance this core holds is always the output of `commit`,
//! `(M + Mᵀ)/2`, whose entries `ij` and `ji` are the same float (`+`
//! commutes): its columns are its rows, which the products below use.

use nalgebra::{ArrayStorage, Matrix2};

use crate::estimation::fusion::config::PoseFilterConfig;
use crate::estimation::fusion::gate::{
    PoseCovariance, PoseFilter, PoseFilterCore, PoseState, PositionMeasurement, STATES, all_finite,
    inverse_2x2,
};
use crate::estimation::fusion::odometry_noise::{OdometryJacobian, linearise_odometry};
use crate::geometry::Vec2;
use crate::math;
use crate::odometry::OdometryStep;

/// The pose EKF.
pub type PoseEkf = PoseFilter<EkfCore>;

/// One row (or column) of a 5×5 matrix.
type Line = [f32; STATES];
/// A 5×5 matrix as five lines: its rows or its columns, as each use says
/// (nalgebra's storage is its columns).
type Lines = [Line; STATES];

/// The EKF of the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EkfCore {
    state: PoseState,
    covariance: PoseCovariance,
}

impl PoseFilterCore for EkfCore {
    fn start(
        _config: &PoseFilterConfig,
        mean: &PoseState,
        covariance: &PoseCovariance,
    ) -> Option<Self> {
        let mut core = Self {
            state: PoseState::zeros(),
            covariance: PoseCovariance::zeros(),
        };
        core.reset(mean, covariance).then_some(core)
    }

    /// Paper 004's predict, `x⁻ = f(x, u)`, `P⁻ = F P Fᵀ + Q`, sparse
    /// (module docs).
    // Not inlined: one copy, called once per tick, instead of one in each
    // caller after LTO.
    #[inline(never)]
    fn predict(&mut self, config: &PoseFilterConfig, odometry: &OdometryStep) -> bool {
        let step = linearise_odometry(config, &self.state, odometry);
        // Rows of F P (P symmetric: its columns are its rows), then the
        // rows of (F P) Fᵀ, row by row.
        let f_p = jacobian_times(&step.jacobian, &self.covariance.data.0);
        let mut predicted = times_jacobian_transpose(&step.jacobian, &f_p);
        // + Q: G Σ Gᵀ on the pose block (module docs of odometry_noise),
        // the scale errors' random walk on their diagonal.
        let [r0, r1, r2, r3, r4] = &mut predicted;
        for (row, noise) in [r0, r1, r2].into_iter().zip(step.pose_noise()) {
            for (entry, q) in row.iter_mut().zip(noise) {
                *entry += q;
            }
        }
        r3[3] += step.scale_walk[0];
        r4[4] += step.scale_walk[1];
        self.commit(step.state, &predicted)
    }

    fn mean(&self) -> PoseState {
        self.state
    }

    fn covariance(&self) -> PoseCovariance {
        self.covariance
    }

    // Not inlined: see `predict`.
    #[inline(never)]
    fn update(&mut self, measurement: &PositionMeasurement) -> bool {
        match *measurement {
            PositionMeasurement::Point { .. } | PositionMeasurement::Ellipse { .. } => measurement
                .position_and_covariance()
                .is_some_and(|(position, r)| self.update_point(position, r)),
            PositionMeasurement::X {
                value_m,
                variance_m2,
            } => self.update_axis(Axis::X, value_m, variance_m2),
            PositionMeasurement::Y {
                value_m,
                variance_m2,
            } => self.update_axis(Axis::Y, value_m, variance_m2),
        }
    }

    fn reset(&mut self, mean: &PoseState, covariance: &PoseCovariance) -> bool {
        let mut state = *mean;
        state.z = math::wrap_angle(mean.z);
        self.commit(state, &covariance.data.0)
    }
}

/// The position axis a 1-D measurement reads.
#[derive(Clone, Copy)]
enum Axis {
    X,
    Y,
}

impl EkfCore {
    /// A 2-D fix: `H = [I₂ 0]`, `ỹ = z − (x̂, ŷ)`, `S = H P Hᵀ + R` (P's
    /// x/y block plus `R`), `K = P Hᵀ S⁻¹` (P's first two columns times
    /// `S⁻¹`, the 2×2 closed form).
    fn update_point(&mut self, position: Vec2, r: Matrix2<f32>) -> bool {
        let innovation = [position.x - self.state.x, position.y - self.state.y];
        let p = &self.covariance;
        let Some([[i00, i01], [i10, i11]]) = inverse_2x2([
            [p.m11 + r.m11, p.m12 + r.m12],
            [p.m21 + r.m21, p.m22 + r.m22],
        ]) else {
            return false;
        };
        let [p0, p1, ..] = &p.data.0;
        // K's columns: P Hᵀ S⁻¹, `P_i0 S⁻¹_0j + P_i1 S⁻¹_1j`.
        let k0 = combine(p0, i00, p1, i10);
        let k1 = combine(p0, i01, p1, i11);
        // K ỹ.
        let correction = combine(&k0, innovation[0], &k1, innovation[1]);
        // I − K H: the identity but for columns 0 and 1, `e_j − K_j`.
        let keep = [minus(&E0, &k0), minus(&E1, &k1)];
        // K R Kᵀ: the columns of K R, then row i of (K R) Kᵀ is
        // `(KR)_i0 K_·0 + (KR)_i1 K_·1`.
        let kr0 = combine(&k0, r.m11, &k1, r.m21);
        let kr1 = combine(&k0, r.m12, &k1, r.m22);
        let mut gain_r_gain = [k0; STATES];
        for ((row, kr_i0), kr_i1) in gain_r_gain.iter_mut().zip(kr0).zip(kr1) {
            *row = combine(&k0, kr_i0, &k1, kr_i1);
        }
        self.apply(correction, &keep, &gain_r_gain)
    }

    /// A 1-D fix on `axis`: `H = e_axisᵀ`, `ỹ = z − x̂_axis`, the scalar
    /// `S = P_aa + σ²`, `K = P_·a / S`.
    fn update_axis(&mut self, axis: Axis, value: f32, variance: f32) -> bool {
        let [p0, p1, ..] = &self.covariance.data.0;
        let (estimate, column, p_aa) = match axis {
            Axis::X => (self.state.x, p0, self.covariance.m11),
            Axis::Y => (self.state.y, p1, self.covariance.m22),
        };
        let innovation = value - estimate;
        let s = p_aa + variance;
        if !(s.is_finite() && s > 0.0) {
            return false;
        }
        let gain = column.map(|p| p / s);
        let correction = scaled(&gain, innovation);
        // I − K H: the identity but for column `axis`, `e_axis − K`.
        let keep = match axis {
            Axis::X => [minus(&E0, &gain), E1],
            Axis::Y => [E0, minus(&E1, &gain)],
        };
        // K σ² Kᵀ, row i `(K_i K) σ²`.
        let mut gain_r_gain = [gain; STATES];
        for (row, ki) in gain_r_gain.iter_mut().zip(gain) {
            scale_twice(row, ki, variance);
        }
        self.apply(correction, &keep, &gain_r_gain)
    }

    /// `x̂ += K ỹ` and the Joseph form `P = (I − KH) P (I − KH)ᵀ + K R Kᵀ`
    /// (paper 004's update; [`crate::estimation::fusion::gate`]), with
    /// `keep` the first two columns of `I − KH` (the rest are the
    /// identity's).
    /// `gain_r_gain` is `K R Kᵀ` by its rows.
    fn apply(&mut self, correction: Line, keep: &[Line; 2], gain_r_gain: &Lines) -> bool {
        let mut state = self.state + PoseState::from(correction);
        state.z = math::wrap_angle(state.z);
        // Rows of A = (I − KH) P (P symmetric: its columns are its rows),
        // then row i of A (I − KH)ᵀ + K R Kᵀ:
        // `A_i0 keep_·0 + A_i1 keep_·1`, plus `A_ij` in columns j ≥ 2.
        let kept = keep_times(keep, &self.covariance.data.0);
        let [keep0, keep1] = keep;
        let mut joseph = kept;
        for ((row, a), krk) in joseph.iter_mut().zip(&kept).zip(gain_r_gain) {
            *row = joseph_row(keep0, keep1, a, krk);
        }
        self.commit(state, &joseph)
    }

    /// The end of every step: `state` and `(M + Mᵀ)/2` of the matrix `M`
    /// given by `lines`, its rows or its columns (`M_ij + M_ji` is the same
    /// float as `M_ji + M_ij`, so either gives the same matrix), become the
    /// filter's if all of them are finite; otherwise nothing changes. (One
    /// copy for predict, update and reset.)
    #[inline(never)]
    fn commit(&mut self, state: PoseState, lines: &Lines) -> bool {
        // (M + Mᵀ)/2 entry by entry, as nalgebra's `(m + m.transpose()) * 0.5`.
        let mut symmetric = *lines;
        for (column, row) in symmetric.iter_mut().zip(transpose(lines)) {
            for (m, t) in column.iter_mut().zip(row) {
                *m = (*m + t) * 0.5;
            }
        }
        let covariance = PoseCovariance::from_data(ArrayStorage(symmetric));
        let finite = all_finite(state.as_slice()) && all_finite(covariance.as_slice());
        if finite {
            self.state = state;
            self.covariance = covariance;
        }
        finite
    }
}

/// The first two unit vectors.
const E0: Line = [1.0, 0.0, 0.0, 0.0, 0.0];
const E1: Line = [0.0, 1.0, 0.0, 0.0, 0.0];

// The products below are made of these few vector steps.

/// `x a`, entry by entry.
fn scaled(x: &Line, a: f32) -> Line {
    x.map(|v| v * a)
}

/// `y += x a`, entry by entry: the step `Σ_k … + A_ik B_kj` of a product.
fn add_scaled(y: &mut Line, x: &Line, a: f32) {
    for (y, x) in y.iter_mut().zip(x) {
        *y += x * a;
    }
}

/// `(x a) b`, entry by entry, in place.
fn scale_twice(x: &mut Line, a: f32, b: f32) {
    for x in x.iter_mut() {
        *x = *x * a * b;
    }
}

/// `x a + y b`, entry by entry: the first two terms of a product.
fn combine(x: &Line, a: f32, y: &Line, b: f32) -> Line {
    let mut out = scaled(x, a);
    add_scaled(&mut out, y, b);
    out
}

/// `x − y`, entry by entry.
fn minus(x: &Line, y: &Line) -> Line {
    let mut out = *x;
    for (o, y) in out.iter_mut().zip(y) {
        *o -= y;
    }
    out
}

/// `x + y`, entry by entry.
fn plus(mut x: Line, y: &Line) -> Line {
    for (x, y) in x.iter_mut().zip(y) {
        *x += y;
    }
    x
}

/// The rows of `Mᵀ` from the rows of `M` (or the columns from the
/// columns).
fn transpose(m: &Lines) -> Lines {
    [
        m.map(|row| row[0]),
        m.map(|row| row[1]),
        m.map(|row| row[2]),
        m.map(|row| row[3]),
        m.map(|row| row[4]),
    ]
}

/// The rows of `F X` from the rows of `X`, for the odometry Jacobian
/// `F = I + (heading column) + (scale columns)`:
/// `(F X)_i = X_i + F_i2 X_2 + F_i3 X_3 + F_i4 X_4` for the pose rows
/// `i = x, y` (`F_22 = 1`: row θ is `X_2 + F_23 X_3 + F_24 X_4`); the scale
/// rows are `X_3, X_4`.
fn jacobian_times(f: &OdometryJacobian, x: &Lines) -> Lines {
    let [_, _, x2, x3, x4] = x;
    let [[fx3, fx4], [fy3, fy4], [ft3, ft4]] = f.scale;
    let [fx2, fy2] = f.heading;
    let mut out = *x;
    let [o0, o1, o2, ..] = &mut out;
    for (row, [f2, f3, f4]) in [o0, o1].into_iter().zip([[fx2, fx3, fx4], [fy2, fy3, fy4]]) {
        add_scaled(row, x2, f2);
        add_scaled(row, x3, f3);
        add_scaled(row, x4, f4);
    }
    add_scaled(o2, x3, ft3);
    add_scaled(o2, x4, ft4);
    out
}

/// Row `i` of `A (I − KH)ᵀ + K R Kᵀ` from row `a` of `A` and row `krk` of
/// `K R Kᵀ`: `a_0 keep_·0 + a_1 keep_·1`, plus `a_j` in columns `j ≥ 2`,
/// plus `krk`.
fn joseph_row(keep0: &Line, keep1: &Line, a: &Line, krk: &Line) -> Line {
    let [a0, a1, a2, a3, a4] = *a;
    let mut b = combine(keep0, a0, keep1, a1);
    b[2] += a2;
    b[3] += a3;
    b[4] += a4;
    plus(b, krk)
}

/// The rows of `M Fᵀ` from the rows of `M`, `F` as in [`jacobian_times`]:
/// `(M Fᵀ)_ij = Σ_k M_ik F_jk`, so columns `j = x, y` are
/// `M_ij + M_i2 F_j2 + M_i3 F_j3 + M_i4 F_j4`, column θ
/// `M_i2 + M_i3 F_23 + M_i4 F_24`, and the scale columns `M_i3, M_i4`.
fn times_jacobian_transpose(f: &OdometryJacobian, m: &Lines) -> Lines {
    m.map(|row| jacobian_transpose_row(f, &row))
}

/// Row `m` of `M` times `Fᵀ` (see [`times_jacobian_transpose`]).
fn jacobian_transpose_row(f: &OdometryJacobian, m: &Line) -> Line {
    let [[fx3, fx4], [fy3, fy4], [ft3, ft4]] = f.scale;
    let [fx2, fy2] = f.heading;
    let [m0, m1, m2, m3, m4] = *m;
    [
        m0 + m2 * fx2 + m3 * fx3 + m4 * fx4,
        m1 + m2 * fy2 + m3 * fy3 + m4 * fy4,
        m2 + m3 * ft3 + m4 * ft4,
        m3,
        m4,
    ]
}

/// The rows of `(I − KH) X` from the rows of `X`, `keep` the first two
/// columns of `I − KH`: `keep_i0 X_0 + keep_i1 X_1`, plus `X_i` for
/// `i ≥ 2`.
fn keep_times(keep: &[Line; 2], x: &Lines) -> Lines {
    let [x0, x1, ..] = x;
    let [keep0, keep1] = *keep;
    let mut out = *x;
    for (i, ((row, a), b)) in out.iter_mut().zip(keep0).zip(keep1).enumerate() {
        let sum = combine(x0, a, x1, b);
        *row = if i < 2 { sum } else { plus(sum, row) };
    }
    out
}

#[cfg(test)]
mod tests {
    //! The sparse filter against a dense EKF of the same equations, to
    //! the bit.
    use super::*;
    use crate::estimation::fusion::odometry_noise::{
        scale_walk_variance, wheel_travels, wheel_variance,
    };
    use nalgebra::{Matrix3x2, SMatrix, Vector2};
    use proptest::prelude::*;

    type Row = SMatrix<f32, 1, STATES>;

    fn symmetric(m: PoseCovariance) -> PoseCovariance {
        (m + m.transpose()) * 0.5
    }

    /// The dense EKF: full matrix products, the reference the sparse
    /// filter matches to the bit.
    #[derive(Clone, Copy)]
    struct Dense {
        state: PoseState,
        covariance: PoseCovariance,
    }

    impl Dense {
        fn predict(&mut self, config: &PoseFilterConfig, odometry: &OdometryStep) -> bool {
            let b = config.track_width_m;
            let (theta, eps_r, eps_l) = (self.state.z, self.state.w, self.state.a);
            let (nominal_r, nominal_l) = wheel_travels(odometry.ds_m, odometry.dtheta_rad, b);
            let (right, left) = (nominal_r * (1.0 + eps_r), nominal_l * (1.0 + eps_l));
            let (ds, dth) = (0.5 * (right + left), (right - left) / b);
            let mid = theta + 0.5 * dth;
            let (sin_m, cos_m) = math::sincos(mid);
            let chord = ds * math::sinc(0.5 * dth);
            let mut next = self.state;
            next.x += chord * cos_m;
            next.y += chord * sin_m;
            next.z = math::wrap_angle(theta + dth);
            let by_step = Matrix3x2::new(
                cos_m,
                -0.5 * chord * sin_m,
                sin_m,
                0.5 * chord * cos_m,
                0.0,
                1.0,
            );
            let by_wheels = by_step * Matrix2::new(0.5, 0.5, 1.0 / b, -1.0 / b);
            let mut jacobian = PoseCovariance::identity();
            jacobian
                .fixed_view_mut::<2, 1>(0, 2)
                .copy_from(&Vector2::new(-chord * sin_m, chord * cos_m));
            let by_scale = by_wheels * Matrix2::new(nominal_r, 0.0, 0.0, nominal_l);
            jacobian.fixed_view_mut::<3, 2>(0, 3).copy_from(&by_scale);
            let noise = Matrix2::from_diagonal(&Vector2::new(
                wheel_variance(config, right),
                wheel_variance(config, left),
            ));
            let mut process_noise = PoseCovariance::zeros();
            process_noise
                .fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&(by_wheels * noise * by_wheels.transpose()));
            process_noise
                .fixed_view_mut::<2, 2>(3, 3)
                .copy_from(&Matrix2::from_diagonal(&Vector2::new(
                    scale_walk_variance(config, right),
                    scale_walk_variance(config, left),
                )));
            let covariance =
                symmetric(jacobian * self.covariance * jacobian.transpose() + process_noise);
            let finite =
                next.iter().all(|x| x.is_finite()) && covariance.iter().all(|x| x.is_finite());
            if finite {
                self.state = next;
                self.covariance = covariance;
            }
            finite
        }

        fn update(&mut self, measurement: &PositionMeasurement) -> bool {
            match *measurement {
                PositionMeasurement::Point { .. } | PositionMeasurement::Ellipse { .. } => {
                    let Some((position, r)) = measurement.position_and_covariance() else {
                        return false;
                    };
                    let h = SMatrix::<f32, 2, STATES>::from_row_slice(&[
                        1.0, 0.0, 0.0, 0.0, 0.0, //
                        0.0, 1.0, 0.0, 0.0, 0.0,
                    ]);
                    let innovation =
                        Vector2::new(position.x - self.state.x, position.y - self.state.y);
                    let s = h * self.covariance * h.transpose() + r;
                    let Some(s_inv) = s.try_inverse() else {
                        return false;
                    };
                    let gain = self.covariance * h.transpose() * s_inv;
                    self.apply(gain * innovation, gain * h, gain * r * gain.transpose())
                }
                PositionMeasurement::X {
                    value_m,
                    variance_m2,
                } => self.update_axis(
                    Row::from_row_slice(&[1.0, 0.0, 0.0, 0.0, 0.0]),
                    value_m,
                    variance_m2,
                ),
                PositionMeasurement::Y {
                    value_m,
                    variance_m2,
                } => self.update_axis(
                    Row::from_row_slice(&[0.0, 1.0, 0.0, 0.0, 0.0]),
                    value_m,
                    variance_m2,
                ),
            }
        }

        fn update_axis(&mut self, h: Row, value: f32, variance: f32) -> bool {
            let innovation = value - (h * self.state).x;
            let s = (h * self.covariance * h.transpose()).x + variance;
            if !(s.is_finite() && s > 0.0) {
                return false;
            }
            let gain = self.covariance * h.transpose() / s;
            self.apply(
                gain * innovation,
                gain * h,
                gain * gain.transpose() * variance,
            )
        }

        fn apply(
            &mut self,
            correction: PoseState,
            gain_h: PoseCovariance,
            gain_r_gain: PoseCovariance,
        ) -> bool {
            let mut state = self.state + correction;
            state.z = math::wrap_angle(state.z);
            let keep = PoseCovariance::identity() - gain_h;
            let covariance = symmetric(keep * self.covariance * keep.transpose() + gain_r_gain);
            let finite =
                state.iter().all(|x| x.is_finite()) && covariance.iter().all(|x| x.is_finite());
            if finite {
                self.state = state;
                self.covariance = covariance;
            }
            finite
        }
    }

    fn config() -> PoseFilterConfig {
        PoseFilterConfig::new(0.2, 3e-5, 1e-8, 3.0).unwrap()
    }

    /// Equal as floats (so `0.0 == -0.0`: a dropped `+ 0·x` may flip the
    /// sign of a zero, and nothing else).
    fn same(sparse: &EkfCore, dense: &Dense) -> bool {
        sparse.state == dense.state && sparse.covariance == dense.covariance
    }

    proptest! {
        /// Predicts and 1-D, 2-D and correlated 2-D updates of the sparse
        /// filter give the dense filter's state and covariance exactly.
        #[test]
        fn sparse_is_the_dense_filter_to_the_bit(
            start in (-5.0f32..5.0, -5.0f32..5.0, -4.0f32..4.0, 0.0f32..0.02),
            variances in (1e-6f32..1.0, 1e-6f32..1.0, 1e-6f32..10.0, 0.0f32..1e-3),
            steps in proptest::collection::vec(
                (-0.02f32..0.02, -0.1f32..0.1, -0.5f32..0.5, -0.5f32..0.5, 0u8..6),
                1..60,
            ),
        ) {
            let (x, y, theta, eps) = start;
            let (vx, vy, vt, ve) = variances;
            let mean = PoseState::from([x, y, theta, eps, -eps]);
            let covariance = PoseCovariance::from_diagonal(&PoseState::from([vx, vy, vt, ve, ve]));
            let config = config();
            let mut sparse = EkfCore::start(&config, &mean, &covariance).unwrap();
            let mut dense = Dense { state: sparse.state, covariance: sparse.covariance };
            for (ds, dth, dx, dy, kind) in steps {
                let odometry = OdometryStep { ds_m: ds, dtheta_rad: dth, ..OdometryStep::default() };
                prop_assert_eq!(sparse.predict(&config, &odometry), dense.predict(&config, &odometry));
                prop_assert!(same(&sparse, &dense), "predict: {:?} vs {:?}", sparse.covariance, dense.covariance);
                let at = Vec2::new(sparse.state.x + dx, sparse.state.y + dy);
                let measurement = match kind {
                    0 => None,
                    1 => Some(PositionMeasurement::X { value_m: at.x, variance_m2: 2e-5 }),
                    2 => Some(PositionMeasurement::Y { value_m: at.y, variance_m2: 3e-6 }),
                    3 => Some(PositionMeasurement::Point { position: at, variance_m2: [1e-4, 3e-4] }),
                    _ => Some(PositionMeasurement::Ellipse {
                        position: at,
                        covariance_m2: [4e-4, 1e-4 * f32::from(kind) - 4.5e-4, 2e-4],
                    }),
                };
                if let Some(m) = measurement {
                    prop_assert_eq!(sparse.update(&m), dense.update(&m));
                    prop_assert!(same(&sparse, &dense), "{:?}: {:?} vs {:?}", m, sparse.covariance, dense.covariance);
                }
                let c = sparse.covariance;
                prop_assert!(c == c.transpose(), "not symmetric to the bit");
            }
        }
    }
}
