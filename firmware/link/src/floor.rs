//! The floor of a run: a tag grid in `Configure`, or a tag map announced
//! there and sent in chunks (the crate docs, "The floor"), and why the
//! firmware refuses a map.

use serde::{Deserialize, Serialize};
use wmr_core::devices::TagMapError;
use wmr_core::devices::tag_grid::TagGridSpec;

use crate::MAP_CHUNK_TAGS;

/// The floor of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FloorSpec {
    /// A regular grid, ids in the core's grid encoding: all of it here.
    Grid(TagGridSpec),
    /// A tag map of `tags` tags (1 to [`MAP_CAPACITY`]), sent next in
    /// [`MapChunk`]s.
    ///
    /// [`MAP_CAPACITY`]: crate::MAP_CAPACITY
    Map {
        /// Tags in the map.
        tags: u16,
    },
}

/// One tag of a tag map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MapTag {
    /// The tag's id (as the reader reports it).
    pub id: u64,
    /// The tag's position, m, world frame.
    pub position_m: [f32; 2],
}

/// Consecutive tags of a tag map, in increasing id order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MapChunk {
    /// Index of the chunk's first tag in the map (the tags loaded before).
    pub first: u16,
    /// The tags.
    pub tags: heapless::Vec<MapTag, MAP_CHUNK_TAGS>,
}

/// Why the firmware refused a tag map.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MapRefusal {
    /// `Configure` announced `tags` tags: none, or more than the firmware
    /// holds.
    Size {
        /// Tags announced.
        tags: u16,
        /// Most the firmware holds ([`MAP_CAPACITY`]).
        ///
        /// [`MAP_CAPACITY`]: crate::MAP_CAPACITY
        capacity: u16,
    },
    /// A chunk arrived while no tag map was being loaded.
    NotLoading,
    /// A chunk did not start at the next tag to load.
    OutOfOrder {
        /// Index of the next tag to load.
        expected: u16,
        /// The chunk's first index.
        first: u16,
    },
    /// A chunk went past the tags `Configure` announced.
    TooMany {
        /// Tags announced.
        announced: u16,
    },
    /// The core's `TagMap` refused a tag (`TagMap::push`).
    Tag {
        /// Index of the tag in the map (the host knows its id).
        index: u16,
        /// Why: a non-finite position, an id not above the one before
        /// (a duplicate, or out of order), the map full.
        why: TagMapError,
    },
}

impl core::fmt::Display for MapRefusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Size { tags, capacity } => write!(
                f,
                "Configure announced {tags} tags; the firmware holds 1 to {capacity}"
            ),
            Self::NotLoading => f.write_str("a map chunk arrived while no tag map was announced"),
            Self::OutOfOrder { expected, first } => write!(
                f,
                "a map chunk starting at tag {first} arrived; tag {expected} was next"
            ),
            Self::TooMany { announced } => {
                write!(f, "map chunks went past the {announced} tags announced")
            }
            Self::Tag { index, why } => write!(f, "tag {index}: {why}"),
        }
    }
}

impl core::error::Error for MapRefusal {}
