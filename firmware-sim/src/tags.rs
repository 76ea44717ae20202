//! The simulated floor: a regular grid of RFID tags ([`FloorTags`]), or a
//! robot file's surveyed tags with arbitrary ids ([`MapFloor`]); a reader
//! sees either as a [`Floor`].
//!
//! Tags lie at `offset + (i·spacing, j·spacing)` for integers `i, j`, over a
//! rectangle that covers the scenario. Ids use the core's grid encoding
//! ([`wmr_core::devices::TagGrid`]: row and column in the id), so the
//! robot needs no table, and the simulator's floor *is* a core `TagGrid`
//! plus the one thing the robot never does: finding the tag nearest to a
//! point (O(1), by rounding to the grid).

use std::sync::Arc;

use wmr_core::devices::{TagGrid, TagGridError, TagId, TagLocator, TagMap, TagMapError};
use wmr_core::geometry::Vec2;

/// Why a floor grid could not be laid.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum FloorError {
    /// Spacing not finite and positive.
    #[error("tag spacing must be finite and positive")]
    Spacing,
    /// Offset or extent not finite, or the extent is empty.
    #[error("tag grid offset and extent must be finite, with min < max")]
    Extent,
    /// More than 65 535 rows or columns.
    #[error("tag grid needs {rows} rows × {columns} columns; at most 65535 of each")]
    TooLarge {
        /// Rows needed.
        rows: u64,
        /// Columns needed.
        columns: u64,
    },
    /// The core refused the grid.
    #[error("the core refused the grid: {0}")]
    Core(TagGridError),
}

/// A tag found on the floor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FloorTag {
    /// The tag's id (core grid encoding).
    pub id: TagId,
    /// The tag's position as the robot computes it from the id (`f32`), m.
    pub position: Vec2,
    /// Distance from the query point to the tag (`f64`), m.
    pub distance_m: f64,
}

/// A regular grid of floor tags covering a rectangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FloorTags {
    grid: TagGrid,
    /// Tag (row 0, column 0), m, in `f64`.
    origin: [f64; 2],
    spacing_m: f64,
}

impl FloorTags {
    /// Lays tags `spacing_m` apart on the lattice through `offset_m`,
    /// covering the rectangle `min_m ..= max_m` (corners `[x, y]`), one
    /// lattice line beyond it on every side if it does not fall on one.
    ///
    /// # Errors
    /// A non-positive spacing, a non-finite or empty rectangle, or more
    /// than 65 535 rows or columns.
    pub fn covering(
        spacing_m: f64,
        offset_m: [f64; 2],
        min_m: [f64; 2],
        max_m: [f64; 2],
    ) -> Result<Self, FloorError> {
        if !(spacing_m.is_finite() && spacing_m > 0.0) {
            return Err(FloorError::Spacing);
        }
        let finite = offset_m
            .iter()
            .chain(&min_m)
            .chain(&max_m)
            .all(|v| v.is_finite());
        if !finite || min_m[0] >= max_m[0] || min_m[1] >= max_m[1] {
            return Err(FloorError::Extent);
        }
        let lo = |a: usize| ((min_m[a] - offset_m[a]) / spacing_m).floor();
        let hi = |a: usize| ((max_m[a] - offset_m[a]) / spacing_m).ceil();
        let (i0, j0) = (lo(0), lo(1));
        let columns = hi(0) - i0 + 1.0;
        let rows = hi(1) - j0 + 1.0;
        if columns > f64::from(u16::MAX) || rows > f64::from(u16::MAX) {
            return Err(FloorError::TooLarge {
                rows: rows as u64,
                columns: columns as u64,
            });
        }
        let origin = [offset_m[0] + i0 * spacing_m, offset_m[1] + j0 * spacing_m];
        let grid = TagGrid::new(
            Vec2::new(origin[0] as f32, origin[1] as f32),
            spacing_m as f32,
            rows as u16,
            columns as u16,
        )
        .map_err(FloorError::Core)?;
        Ok(Self {
            grid,
            origin,
            spacing_m,
        })
    }

    /// The core grid (give it to the robot as its [`TagLocator`]).
    #[must_use]
    pub fn grid(&self) -> &TagGrid {
        &self.grid
    }

    /// Spacing between neighbouring tags, m.
    #[must_use]
    pub fn spacing_m(&self) -> f64 {
        self.spacing_m
    }

    /// Number of tags on the floor.
    #[must_use]
    pub fn len(&self) -> usize {
        usize::from(self.grid.rows()) * usize::from(self.grid.columns())
    }

    /// Whether the floor has no tags (never: a grid has at least one).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The rectangle the tags cover, `([x_min, y_min], [x_max, y_max])`, m.
    #[must_use]
    pub fn bounds(&self) -> ([f64; 2], [f64; 2]) {
        let s = self.spacing_m;
        (
            self.origin,
            [
                self.origin[0] + f64::from(self.grid.columns() - 1) * s,
                self.origin[1] + f64::from(self.grid.rows() - 1) * s,
            ],
        )
    }

    /// The installed tag nearest to `(x_m, y_m)`: rounds to the lattice,
    /// then clamps to the installed rows and columns (outside the covered
    /// rectangle the nearest tag is on its edge).
    #[must_use]
    pub fn nearest(&self, x_m: f64, y_m: f64) -> FloorTag {
        let index = |v: f64, o: f64, n: u16| -> u16 {
            let i = ((v - o) / self.spacing_m).round();
            if i.is_nan() {
                0
            } else {
                i.clamp(0.0, f64::from(n - 1)) as u16
            }
        };
        let column = index(x_m, self.origin[0], self.grid.columns());
        let row = index(y_m, self.origin[1], self.grid.rows());
        let id = TagGrid::id(row, column);
        let (tx, ty) = (
            self.origin[0] + f64::from(column) * self.spacing_m,
            self.origin[1] + f64::from(row) * self.spacing_m,
        );
        FloorTag {
            id,
            position: self.grid.locate(id).unwrap_or_default(),
            distance_m: (tx - x_m).hypot(ty - y_m),
        }
    }
}

impl TagLocator for FloorTags {
    fn locate(&self, id: TagId) -> Option<Vec2> {
        self.grid.locate(id)
    }
}

/// Most tags a [`MapFloor`] holds: the flash image's table
/// (`scenario::robot::MAX_MAPPED_TAGS`).
pub const MAX_MAP_TAGS: usize = 4096;

/// The robot's table of a tag-map floor: the core's [`TagMap`] (binary
/// search over sorted ids, `f32` positions: the lookup the Black Pill's
/// image table makes, `wmr_link::image::ImageTags`).
pub type MapTable = TagMap<MAX_MAP_TAGS>;

/// A floor of surveyed tags with arbitrary ids (a robot file's
/// `floor.kind = "tag_map"`).
///
/// The reader model sees each tag at its surveyed position (`f64`); the
/// robot resolves the id it reads through [`MapTable`], the position
/// rounded to `f32` as in the firmware's flash table.
#[derive(Debug, Clone, PartialEq)]
pub struct MapFloor {
    /// `(id, [x, y])`, m, sorted by id.
    tags: Vec<(TagId, [f64; 2])>,
    table: Box<MapTable>,
}

impl MapFloor {
    /// The floor of `tags` (`(id, [x, y])`, m, any order).
    ///
    /// # Errors
    /// The core's [`TagMap`] refusal: more than [`MAX_MAP_TAGS`] tags, a
    /// duplicate id or a position that is not finite in `f32`; or no tags
    /// ([`TagMapError::Full`] is never returned for that: `None` is).
    pub fn new(tags: &[(TagId, [f64; 2])]) -> Result<Option<Self>, TagMapError> {
        if tags.is_empty() {
            return Ok(None);
        }
        let mut table = Box::new(MapTable::new());
        for &(id, [x, y]) in tags {
            table.insert(id, Vec2::new(x as f32, y as f32))?;
        }
        let mut tags = tags.to_vec();
        tags.sort_by_key(|t| t.0.0);
        Ok(Some(Self { tags, table }))
    }

    /// Number of tags.
    #[must_use]
    pub fn len(&self) -> usize {
        self.tags.len()
    }

    /// Whether there are none (never: [`Self::new`] refuses an empty map).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.tags.is_empty()
    }

    /// The robot's table.
    #[must_use]
    pub fn table(&self) -> &MapTable {
        &self.table
    }

    /// The tag nearest to `(x_m, y_m)` (Euclidean; of equally near tags the
    /// lowest id), as [`FloorTags::nearest`] finds it on a grid.
    #[must_use]
    pub fn nearest(&self, x_m: f64, y_m: f64) -> FloorTag {
        let mut best: Option<(TagId, f64)> = None;
        for &(id, [tx, ty]) in &self.tags {
            let d = (tx - x_m).hypot(ty - y_m);
            if best.is_none_or(|(_, b)| d < b) {
                best = Some((id, d));
            }
        }
        let (id, distance_m) = best.unwrap_or((TagId(0), f64::INFINITY));
        FloorTag {
            id,
            position: self.table.position(id).unwrap_or_default(),
            distance_m,
        }
    }
}

/// The floor a reader sees and the robot looks its ids up in: a grid or a
/// tag map.
#[derive(Debug, Clone, PartialEq)]
pub enum Floor {
    /// A regular grid, ids in the core's grid encoding.
    Grid(FloorTags),
    /// Surveyed tags with arbitrary ids (shared: one per scenario).
    Map(Arc<MapFloor>),
}

impl Floor {
    /// The tag nearest to `(x_m, y_m)`.
    #[must_use]
    pub fn nearest(&self, x_m: f64, y_m: f64) -> FloorTag {
        match self {
            Self::Grid(grid) => grid.nearest(x_m, y_m),
            Self::Map(map) => map.nearest(x_m, y_m),
        }
    }

    /// Number of tags on the floor.
    #[must_use]
    pub fn len(&self) -> usize {
        match self {
            Self::Grid(grid) => grid.len(),
            Self::Map(map) => map.len(),
        }
    }

    /// Whether the floor has no tags (never).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The grid's spacing, m (`None` for a tag map).
    #[must_use]
    pub fn spacing_m(&self) -> Option<f64> {
        match self {
            Self::Grid(grid) => Some(grid.spacing_m()),
            Self::Map(_) => None,
        }
    }

    /// The grid (`None` for a tag map).
    #[must_use]
    pub fn grid(&self) -> Option<&FloorTags> {
        match self {
            Self::Grid(grid) => Some(grid),
            Self::Map(_) => None,
        }
    }
}

impl TagLocator for Floor {
    /// The core's grid or the core's tag map: what the robot's firmware
    /// looks the id up in.
    fn locate(&self, id: TagId) -> Option<Vec2> {
        match self {
            Self::Grid(grid) => grid.locate(id),
            Self::Map(map) => map.table().position(id),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rounds_and_clamps() {
        let f = FloorTags::covering(0.1, [0.0, 0.0], [-1.0, -2.0], [1.0, 1.0]).unwrap();
        assert_eq!(f.len(), 21 * 31);
        let t = f.nearest(0.26, -0.04);
        assert!((t.position.x - 0.3).abs() < 1e-6 && t.position.y.abs() < 1e-6);
        assert!((t.distance_m - (0.04_f64.hypot(0.04))).abs() < 1e-9);
        // Outside: the edge tag.
        let t = f.nearest(5.0, -7.0);
        assert!((t.position.x - 1.0).abs() < 1e-5 && (t.position.y + 2.0).abs() < 1e-5);
        assert_eq!(f.locate(t.id), Some(t.position));
    }

    #[test]
    fn offset_lattice() {
        let f = FloorTags::covering(0.1, [0.05, 0.05], [-1.0, -1.0], [1.0, 1.0]).unwrap();
        let t = f.nearest(0.0, 0.0);
        assert!((t.position.x.abs() - 0.05).abs() < 1e-6);
        assert!((t.position.y.abs() - 0.05).abs() < 1e-6);
        let (lo, hi) = f.bounds();
        assert!(lo[0] <= -1.0 && hi[0] >= 1.0 && lo[1] <= -1.0 && hi[1] >= 1.0);
    }

    #[test]
    fn bad_grids_are_refused() {
        assert_eq!(
            FloorTags::covering(0.0, [0.0; 2], [0.0; 2], [1.0; 2]),
            Err(FloorError::Spacing)
        );
        assert_eq!(
            FloorTags::covering(0.1, [0.0; 2], [1.0; 2], [1.0; 2]),
            Err(FloorError::Extent)
        );
        assert!(matches!(
            FloorTags::covering(1e-4, [0.0; 2], [0.0; 2], [10.0; 2]),
            Err(FloorError::TooLarge { .. })
        ));
    }

    #[test]
    fn a_map_finds_what_the_grid_finds() {
        // The grid's tags under other ids: the same nearest tag, distance
        // and position everywhere.
        let grid = FloorTags::covering(0.1, [0.0, 0.0], [-0.5, -0.3], [0.5, 0.3]).unwrap();
        let tags: Vec<(TagId, [f64; 2])> = (0..grid.grid().rows())
            .flat_map(|row| (0..grid.grid().columns()).map(move |column| (row, column)))
            .enumerate()
            .map(|(n, (row, column))| {
                let p = grid.grid().position(TagGrid::id(row, column)).unwrap();
                (TagId(1000 - n as u64), [f64::from(p.x), f64::from(p.y)])
            })
            .collect();
        let map = MapFloor::new(&tags).unwrap().unwrap();
        assert_eq!(map.len(), grid.len());
        for (x, y) in [(0.26, -0.04), (-0.49, 0.29), (0.013, 0.151), (3.0, -4.0)] {
            let (g, m) = (grid.nearest(x, y), map.nearest(x, y));
            assert_eq!(g.position, m.position, "at ({x}, {y})");
            assert!((g.distance_m - m.distance_m).abs() < 1e-6);
            assert_eq!(
                Floor::Map(Arc::new(map.clone())).locate(m.id),
                Some(m.position)
            );
        }
        assert_eq!(Floor::Map(Arc::new(map)).locate(TagId(1001)), None);
    }

    #[test]
    fn a_bad_map_is_refused_by_the_core() {
        let t = |id, x| (TagId(id), [x, 0.0]);
        assert_eq!(MapFloor::new(&[]), Ok(None));
        assert_eq!(
            MapFloor::new(&[t(1, 0.0), t(1, 1.0)]),
            Err(TagMapError::DuplicateId)
        );
        assert_eq!(
            MapFloor::new(&[t(1, 1e300)]),
            Err(TagMapError::NonFinitePosition)
        );
        let many: Vec<_> = (0..=MAX_MAP_TAGS as u64).map(|i| t(i, 0.0)).collect();
        assert_eq!(MapFloor::new(&many), Err(TagMapError::Full));
    }
}
