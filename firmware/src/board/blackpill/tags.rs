//! The floor-tag map, compiled into flash.
//!
//! The core's `TagMap` is a `heapless::Vec` filled at run time (so it lives
//! in RAM), and its `TagGrid` computes positions from ids written for a
//! grid. A surveyed site is a fixed list of `(id, position)` pairs, so here
//! it is a `const` slice in `.rodata` (flash; nothing is copied to RAM),
//! wrapped in [`FlashTagTable`], which implements the core's [`TagLocator`]
//! with a binary search over the ids.
//!
//! **[`SITE_TAGS`] is an example**, to be replaced by the site survey: seven
//! tags at the turning points and the crossing of the figure-eight the
//! pilot tracks (`x = 5 sin 2s`, `y = 5 sin s`, m). The tracker needs a fix
//! at least every `fix_timeout_ticks` (0.5 s); at the reference's top speed
//! (0.22 m/s) that is one tag every 11 cm along the path, which is why the
//! simulator's floor is a 10 cm grid. With only these seven the robot spends
//! most of its time in the failsafe (decelerating to a stop).
//!
//! Built with `cargo xtask firmware --robot FILE`, the robot image's floor
//! replaces this table (`robots/blackpill.toml` is this one as a robot file).
#![cfg_attr(wmr_robot_image, allow(dead_code))]

use wmr_core::devices::{TagId, TagLocator};
use wmr_core::geometry::Vec2;

/// One surveyed tag.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TagEntry {
    /// The id the reader reports (40 bits).
    pub id: TagId,
    /// Floor position of the tag, m, world frame.
    pub position: Vec2,
}

/// A tag table in flash, sorted by id.
#[derive(Debug, Clone, Copy)]
pub struct FlashTagTable {
    /// Strictly increasing ids, 40-bit, finite positions (checked by [`Self::new`]).
    entries: &'static [TagEntry],
}

impl FlashTagTable {
    /// The table, or `None` if an id is wider than 40 bits, the ids are not
    /// strictly increasing (sorted, no duplicates), or a position is not
    /// finite. Used in a `const` (see [`SITE_TAGS`]), so a bad table is a
    /// compile error, never a run-time failure.
    pub const fn new(entries: &'static [TagEntry]) -> Option<Self> {
        let mut i = 0;
        while i < entries.len() {
            let e = &entries[i];
            if e.id.0 > TagId::MASK || !e.position.x.is_finite() || !e.position.y.is_finite() {
                return None;
            }
            if i > 0 && entries[i - 1].id.0 >= e.id.0 {
                return None;
            }
            i += 1;
        }
        Some(Self { entries })
    }

    /// Number of tags.
    pub const fn len(&self) -> usize {
        self.entries.len()
    }
}

impl TagLocator for FlashTagTable {
    /// Binary search over the sorted ids: O(log N), no allocation.
    fn locate(&self, id: TagId) -> Option<Vec2> {
        let at = self.entries.binary_search_by_key(&id, |e| e.id).ok()?;
        self.entries.get(at).map(|e| e.position)
    }
}

/// `5 · sin(π/4)`, m.
const H1_SIN_45: f32 = 3.535_534;

/// The example survey: sorted by id. Replace with the site's.
const SURVEY: &[TagEntry] = &[
    // s = -π/2: the reference's start point.
    TagEntry {
        id: TagId(0x01_0000_0001),
        position: Vec2::new(0.0, -5.0),
    },
    // s = -π/4: left lobe, lower turn.
    TagEntry {
        id: TagId(0x01_0000_0002),
        position: Vec2::new(-5.0, -H1_SIN_45),
    },
    // s = 0 and π: the crossing.
    TagEntry {
        id: TagId(0x01_0000_0003),
        position: Vec2::new(0.0, 0.0),
    },
    // s = π/4: right lobe, upper turn.
    TagEntry {
        id: TagId(0x01_0000_0004),
        position: Vec2::new(5.0, H1_SIN_45),
    },
    // s = π/2: top.
    TagEntry {
        id: TagId(0x01_0000_0005),
        position: Vec2::new(0.0, 5.0),
    },
    // s = 3π/4: left lobe, upper turn.
    TagEntry {
        id: TagId(0x01_0000_0006),
        position: Vec2::new(-5.0, H1_SIN_45),
    },
    // s = 5π/4: right lobe, lower turn.
    TagEntry {
        id: TagId(0x01_0000_0007),
        position: Vec2::new(5.0, -H1_SIN_45),
    },
];

/// The site's tags (an example: see the module documentation).
pub const SITE_TAGS: FlashTagTable = match FlashTagTable::new(SURVEY) {
    Some(table) => table,
    None => panic!("tag table: ids must be 40-bit and strictly increasing, positions finite"),
};
