//! Tag positions without a table: a regular floor grid whose tag ids encode
//! their row and column.
//!
//! A 10 cm grid over a 12 m × 12 m floor is 14 400 tags: as a table
//! ([`super::TagMap`]) that is 230 KiB, more than the RAM of the robot's
//! MCU. Tags written for a grid installation instead carry their grid
//! coordinates in their id, and the position is computed:
//!
//! ```text
//! id (40 bits) = 0x5A (8-bit installation marker) << 32 | row (16 bits) << 16 | column (16 bits)
//! position     = origin + (column · spacing, row · spacing)
//! ```
//!
//! An id without the marker, or outside the installed rows/columns, is an
//! unknown tag (the caller counts it), never a position.

use crate::devices::TagId;
use crate::geometry::Vec2;
use crate::plausible::{COORDINATE_M, TAG_SPACING_M};

/// Marker in bits 32..40 of every grid tag id.
pub const GRID_MARKER: u64 = 0x5A;

/// Why a [`TagGrid`] was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum TagGridError {
    /// Spacing outside [`TAG_SPACING_M`].
    Spacing,
    /// Origin outside [`COORDINATE_M`] on an axis.
    Origin,
    /// No rows or no columns.
    Size,
}

impl core::fmt::Display for TagGridError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Spacing => write!(f, "spacing_m must be in {TAG_SPACING_M} m"),
            Self::Origin => write!(f, "origin_m must be in {COORDINATE_M} m on each axis"),
            Self::Size => f.write_str("rows and columns must each be ≥ 1"),
        }
    }
}

impl core::error::Error for TagGridError {}

/// A regular grid of floor tags.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TagGrid {
    origin: Vec2,
    spacing_m: f32,
    rows: u16,
    columns: u16,
}

impl TagGrid {
    /// A grid whose tag (row 0, column 0) lies at `origin` (m), with
    /// `spacing_m` between neighbours, `rows × columns` tags.
    ///
    /// # Errors
    /// The first parameter outside its plausible range ([`crate::plausible`]).
    pub fn new(
        origin: Vec2,
        spacing_m: f32,
        rows: u16,
        columns: u16,
    ) -> Result<Self, TagGridError> {
        if !TAG_SPACING_M.contains(spacing_m) {
            return Err(TagGridError::Spacing);
        }
        if !(COORDINATE_M.contains(origin.x) && COORDINATE_M.contains(origin.y)) {
            return Err(TagGridError::Origin);
        }
        if rows == 0 || columns == 0 {
            return Err(TagGridError::Size);
        }
        Ok(Self {
            origin,
            spacing_m,
            rows,
            columns,
        })
    }

    /// The id of the tag at `(row, column)`.
    #[must_use]
    pub fn id(row: u16, column: u16) -> TagId {
        TagId(GRID_MARKER << 32 | u64::from(row) << 16 | u64::from(column))
    }

    /// Spacing between neighbouring tags, m.
    #[must_use]
    pub fn spacing_m(&self) -> f32 {
        self.spacing_m
    }

    /// Position of tag (0, 0), m.
    #[must_use]
    pub fn origin(&self) -> Vec2 {
        self.origin
    }

    /// Number of rows (along y).
    #[must_use]
    pub fn rows(&self) -> u16 {
        self.rows
    }

    /// Number of columns (along x).
    #[must_use]
    pub fn columns(&self) -> u16 {
        self.columns
    }

    /// `(row, column)` of a grid id inside this installation.
    #[must_use]
    pub fn cell(&self, id: TagId) -> Option<(u16, u16)> {
        if id.0 >> 32 != GRID_MARKER {
            return None;
        }
        let row = ((id.0 >> 16) & 0xFFFF) as u16;
        let column = (id.0 & 0xFFFF) as u16;
        (row < self.rows && column < self.columns).then_some((row, column))
    }

    /// Floor position of a grid tag, m.
    #[must_use]
    pub fn position(&self, id: TagId) -> Option<Vec2> {
        self.cell(id).map(|(row, column)| {
            Vec2::new(
                self.origin.x + f32::from(column) * self.spacing_m,
                self.origin.y + f32::from(row) * self.spacing_m,
            )
        })
    }
}

/// Anything that turns a tag id into a floor position.
pub trait TagLocator {
    /// The tag's floor position (m, world frame), or `None` for an unknown tag.
    fn locate(&self, id: TagId) -> Option<Vec2>;
}

impl TagLocator for TagGrid {
    fn locate(&self, id: TagId) -> Option<Vec2> {
        self.position(id)
    }
}

impl<const N: usize> TagLocator for super::TagMap<N> {
    fn locate(&self, id: TagId) -> Option<Vec2> {
        self.position(id)
    }
}

impl<T: TagLocator + ?Sized> TagLocator for &T {
    fn locate(&self, id: TagId) -> Option<Vec2> {
        (**self).locate(id)
    }
}

/// A regular floor-tag grid ([`TagGrid::new`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TagGridSpec {
    /// Position of tag (row 0, column 0), m, each axis in
    /// [`crate::plausible::COORDINATE_M`].
    pub origin_m: [f32; 2],
    /// Spacing between neighbours, m, in [`crate::plausible::TAG_SPACING_M`].
    pub spacing_m: f32,
    /// Rows (along y).
    pub rows: u16,
    /// Columns (along x).
    pub columns: u16,
}

impl TagGridSpec {
    /// The validated grid.
    ///
    /// # Errors
    /// The grid's refusal.
    pub fn build(&self) -> Result<TagGrid, TagGridError> {
        let [x, y] = self.origin_m;
        TagGrid::new(Vec2::new(x, y), self.spacing_m, self.rows, self.columns)
    }

    /// The spec of a grid (inverse of [`Self::build`]).
    #[must_use]
    pub fn of(grid: &TagGrid) -> Self {
        let origin = grid.origin();
        Self {
            origin_m: [origin.x, origin.y],
            spacing_m: grid.spacing_m(),
            rows: grid.rows(),
            columns: grid.columns(),
        }
    }
}

/// A grid drawn from a fuzzer's bytes: 21 × 21 tags, 0.1 m apart, around
/// the origin most of the time ([`crate::fuzzing`]).
#[cfg(feature = "arbitrary")]
impl<'a> arbitrary::Arbitrary<'a> for TagGridSpec {
    fn arbitrary(u: &mut arbitrary::Unstructured<'a>) -> arbitrary::Result<Self> {
        use crate::fuzzing::float;
        Ok(Self {
            origin_m: [float(u, -1.0)?, float(u, -1.0)?],
            spacing_m: float(u, 0.1)?,
            rows: if u.ratio(7, 8)? { 21 } else { u.arbitrary()? },
            columns: if u.ratio(7, 8)? { 21 } else { u.arbitrary()? },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_round_trip_to_positions() {
        let g = TagGrid::new(Vec2::new(-6.0, -6.0), 0.1, 121, 121).unwrap();
        let p = g.locate(TagGrid::id(60, 0)).unwrap();
        assert!((p.x + 6.0).abs() < 1e-6 && p.y.abs() < 1e-5);
        assert_eq!(g.cell(TagGrid::id(120, 120)), Some((120, 120)));
    }

    #[test]
    fn foreign_and_out_of_grid_ids_are_unknown() {
        let g = TagGrid::new(Vec2::ZERO, 0.1, 10, 10).unwrap();
        assert_eq!(g.locate(TagGrid::id(10, 0)), None);
        assert_eq!(g.locate(TagGrid::id(0, 10)), None);
        assert_eq!(g.locate(TagId(0x12_3456_7890)), None);
    }

    #[test]
    fn construction_is_validated() {
        assert_eq!(
            TagGrid::new(Vec2::ZERO, 0.0, 1, 1),
            Err(TagGridError::Spacing)
        );
        assert_eq!(TagGrid::new(Vec2::ZERO, 0.1, 0, 1), Err(TagGridError::Size));
    }

    #[test]
    fn grid_spec_round_trips() {
        let spec = TagGridSpec {
            origin_m: [-6.0, -6.5],
            spacing_m: 0.1,
            rows: 130,
            columns: 120,
        };
        let grid = spec.build().unwrap();
        assert_eq!(TagGridSpec::of(&grid), spec);
        let bad = TagGridSpec { rows: 0, ..spec };
        assert_eq!(bad.build(), Err(TagGridError::Size));
    }
}
