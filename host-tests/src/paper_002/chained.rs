//! Paper 002, section 2: simulations of the chained form (figures 2, 3).

use super::Figure;

/// The section 2.3 figures (filled in with the simulations).
#[must_use]
pub fn figures() -> Vec<Figure> {
    Vec::new()
}
