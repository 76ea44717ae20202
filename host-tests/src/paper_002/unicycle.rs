//! Paper 002, section 3: simulations of the mobile car (figures 4 to 8).

use super::Figure;

/// The section 3 figures (filled in with the simulations).
#[must_use]
pub fn figures() -> Vec<Figure> {
    Vec::new()
}
