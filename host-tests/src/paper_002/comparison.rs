//! The comparison table of every position-only pairing (the unicycle
//! runs) and of the chained form with the heading measured, side by side.

use super::chained::figure_eight_with_measured_heading;
use super::unicycle::{Pairing, figure_eight_comparison};

/// The comparison as a markdown table, with the pairings that cannot run
/// on position-only data and why.
#[must_use]
pub fn comparison_markdown() -> String {
    let mut md = String::from(
        "| estimator + controller | max (m) | mean (m) | RMS (m) |\n| --- | ---: | ---: | ---: |\n",
    );
    for pairing in Pairing::ALL {
        let (s, _) = figure_eight_comparison(pairing);
        md.push_str(&format!(
            "| {} | {:.4} | {:.4} | {:.4} |\n",
            pairing.label(),
            s.max_m,
            s.mean_m,
            s.rms_m
        ));
    }
    let (s, _) = figure_eight_with_measured_heading(10.0, 100.0);
    md.push_str(&format!(
        "| 002 Prop. 3 (25)–(26) through (6), **heading measured exactly** (not position-only; \
         c1 = c2 = 0.5, c3 = 10, a1 = 100) | {:.4} | {:.4} | {:.4} |\n",
        s.max_m, s.mean_m, s.rms_m
    ));
    for (label, why) in [
        (
            "002 Prop. 1–3 (chained form (10), (14)/(16), (25)–(26))",
            "needs `x1 = θ` and `x3 = x sin θ − y cos θ` measured: the heading is what RFID does not give",
        ),
        (
            "002 Prop. 5 (observer of `y_e`) + (31)",
            "needs `x_e` and `θ_e` measured (robot-frame errors and the heading error)",
        ),
        (
            "002 Prop. 6 (observer of `x_e`) + (50)",
            "needs `y_e` and `θ_e` measured",
        ),
    ] {
        md.push_str(&format!("| {label} | n/a: {why} | | |\n"));
    }
    md
}
