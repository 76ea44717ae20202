//! Simulations of paper 002 (Jakubiak, Nijmeijer & Lefeber), shared by the
//! tests (`tests/paper_002_*.rs`), which assert on them, and the example
//! `paper_002_figures`, which plots them on semilog axes like the paper's
//! figures.
//!
//! * [`chained`]: section 2, the chained form (figures 2 and 3).
//! * [`unicycle`]: section 3, the mobile car (figures 4 to 8) and the
//!   position-only comparison on paper 001's figure-eight.

pub mod chained;
pub mod comparison;
pub mod unicycle;

/// One curve of a figure: `(t [s], value)` points.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend label (e.g. `|x̃2|`).
    pub label: String,
    /// `(t, value)` samples; plotted as `|value|` on a log axis.
    pub points: Vec<(f64, f64)>,
}

impl Series {
    /// `|value|` at the first sample at or after `t` (NaN past the end).
    #[must_use]
    pub fn abs_at(&self, t: f64) -> f64 {
        self.points
            .iter()
            .find(|p| p.0 >= t - 1e-9)
            .map_or(f64::NAN, |p| p.1.abs())
    }

    /// Largest `|value|` over the samples with `from ≤ t ≤ to` (0 if none).
    #[must_use]
    pub fn max_abs_over(&self, from: f64, to: f64) -> f64 {
        self.points
            .iter()
            .filter(|p| p.0 >= from && p.0 <= to)
            .map(|p| p.1.abs())
            .fold(0.0, f64::max)
    }

    /// An empty series with this legend label.
    #[must_use]
    pub fn new(label: &str) -> Self {
        Self {
            label: label.to_string(),
            points: Vec::new(),
        }
    }
}

/// A figure of the paper, as data.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// File name without extension, e.g. `fig2a_u1_const`.
    pub name: String,
    /// Title, citing the paper's figure, e.g. `Fig. 2(a): u1 = 1, a2 = 1000, a3 = 100`.
    pub title: String,
    /// Curves, all plotted as absolute values on a log axis.
    pub series: Vec<Series>,
}

/// Least-squares slope of `ln|value|` against `t` over `[from_s, to_s]`
/// (samples with `|value| > floor` only): the fitted exponential decay
/// rate, 1/s (negative = decaying). `None` with fewer than two samples.
#[must_use]
pub fn log_decay_rate(points: &[(f64, f64)], from_s: f64, to_s: f64, floor: f64) -> Option<f64> {
    let samples: Vec<(f64, f64)> = points
        .iter()
        .filter(|(t, v)| *t >= from_s && *t <= to_s && v.abs() > floor && v.is_finite())
        .map(|&(t, v)| (t, v.abs().ln()))
        .collect();
    if samples.len() < 2 {
        return None;
    }
    let n = samples.len() as f64;
    let (st, sl) = samples
        .iter()
        .fold((0.0, 0.0), |(a, b), (t, l)| (a + t, b + l));
    let (mt, ml) = (st / n, sl / n);
    let (num, den) = samples.iter().fold((0.0, 0.0), |(a, b), (t, l)| {
        (a + (t - mt) * (l - ml), b + (t - mt) * (t - mt))
    });
    (den > 0.0).then(|| num / den)
}

#[cfg(test)]
mod tests {
    use super::log_decay_rate;

    #[test]
    fn fits_an_exponential() {
        let points: Vec<(f64, f64)> = (0..100)
            .map(|i| {
                let t = f64::from(i) * 0.1;
                (t, 3.0 * (-0.7 * t).exp())
            })
            .collect();
        let rate = log_decay_rate(&points, 0.0, 10.0, 0.0).unwrap();
        assert!((rate + 0.7).abs() < 1e-9, "{rate}");
        assert_eq!(log_decay_rate(&points[..1], 0.0, 10.0, 0.0), None);
    }
}
