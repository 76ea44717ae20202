//! Floor map of the RFID tags: tag id → position of the tag, world frame.
//!
//! Backed by a fixed-capacity [`heapless::Vec`] kept sorted by id, so a
//! lookup is a binary search (O(log N)) and nothing is allocated. Inserting
//! is O(N) (it shifts the tail), which is fine: maps are built once, at
//! start-up.

use crate::devices::rfid::TagId;
use crate::geometry::Vec2;

/// Why a tag was not added to a [`TagMap`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum TagMapError {
    /// The map holds `N` tags already.
    Full,
    /// The id is in the map already (with whatever position).
    DuplicateId,
    /// A coordinate of the position is NaN or infinite.
    NonFinitePosition,
    /// [`TagMap::push`]: the id is below the last mapped id.
    Unsorted,
}

impl core::fmt::Display for TagMapError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::Full => "tag map full",
            Self::DuplicateId => "tag id already in the map",
            Self::NonFinitePosition => "tag position not finite",
            Self::Unsorted => "tag id below the one before it (ids must increase)",
        })
    }
}

impl core::error::Error for TagMapError {}

/// One tag of the map.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Entry {
    id: TagId,
    position: Vec2,
}

/// Up to `N` tags with their floor positions (metres, world frame).
///
/// Ids are compared as stored in [`TagId`] (all 64 bits); the reader only
/// ever produces 40-bit ids.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TagMap<const N: usize> {
    /// Sorted by id, ids unique.
    entries: heapless::Vec<Entry, N>,
}

impl<const N: usize> TagMap<N> {
    /// An empty map.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            entries: heapless::Vec::new(),
        }
    }

    /// Adds a tag at `position` (metres, world frame).
    ///
    /// # Errors
    /// [`TagMapError::NonFinitePosition`] if a coordinate is NaN or
    /// infinite, [`TagMapError::DuplicateId`] if `id` is already mapped,
    /// [`TagMapError::Full`] if `N` tags are mapped; checked in that order.
    /// The map is unchanged on error.
    pub fn insert(&mut self, id: TagId, position: Vec2) -> Result<(), TagMapError> {
        if !position.is_finite() {
            return Err(TagMapError::NonFinitePosition);
        }
        match self.entries.binary_search_by_key(&id, |e| e.id) {
            Ok(_) => Err(TagMapError::DuplicateId),
            Err(at) => self
                .entries
                .insert(at, Entry { id, position })
                .map_err(|_| TagMapError::Full),
        }
    }

    /// Adds a tag whose id is above every mapped id: a map sent or stored
    /// in increasing id order is built with this, O(1) (no tail to shift,
    /// so a firmware that builds its map only so links no `memmove`).
    ///
    /// # Errors
    /// [`TagMapError::NonFinitePosition`] if a coordinate is NaN or
    /// infinite, [`TagMapError::DuplicateId`] if `id` is the last mapped
    /// id, [`TagMapError::Unsorted`] if it is below it,
    /// [`TagMapError::Full`] if `N` tags are mapped; checked in that order.
    /// The map is unchanged on error.
    pub fn push(&mut self, id: TagId, position: Vec2) -> Result<(), TagMapError> {
        if !position.is_finite() {
            return Err(TagMapError::NonFinitePosition);
        }
        match self.entries.last() {
            Some(last) if last.id == id => Err(TagMapError::DuplicateId),
            Some(last) if last.id > id => Err(TagMapError::Unsorted),
            _ => self
                .entries
                .push(Entry { id, position })
                .map_err(|_| TagMapError::Full),
        }
    }

    /// The position of tag `id`, if mapped.
    #[must_use]
    pub fn position(&self, id: TagId) -> Option<Vec2> {
        let at = self.entries.binary_search_by_key(&id, |e| e.id).ok()?;
        self.entries.get(at).map(|e| e.position)
    }

    /// Whether tag `id` is mapped.
    #[must_use]
    pub fn contains(&self, id: TagId) -> bool {
        self.position(id).is_some()
    }

    /// Number of mapped tags.
    #[must_use]
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether no tag is mapped.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Removes every tag, in place (a map of thousands of tags is reused,
    /// never rebuilt on the stack).
    pub fn clear(&mut self) {
        self.entries.clear();
    }

    /// Most tags the map can hold (`N`).
    #[must_use]
    pub const fn capacity(&self) -> usize {
        N
    }

    /// The mapped tags and their positions, in increasing id order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = (TagId, Vec2)> + '_ {
        self.entries.iter().map(|e| (e.id, e.position))
    }
}

impl<const N: usize> Default for TagMap<N> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::BTreeMap;
    use std::vec::Vec;

    #[test]
    fn lookup_hits_and_misses() {
        let mut m = TagMap::<8>::new();
        assert!(m.is_empty());
        assert_eq!(m.position(TagId(1)), None);
        m.insert(TagId(30), Vec2::new(3.0, 0.5)).unwrap();
        m.insert(TagId(10), Vec2::new(1.0, 0.5)).unwrap();
        m.insert(TagId(20), Vec2::new(2.0, -0.5)).unwrap();
        assert_eq!(m.len(), 3);
        assert_eq!(m.capacity(), 8);
        assert_eq!(m.position(TagId(20)), Some(Vec2::new(2.0, -0.5)));
        assert_eq!(m.position(TagId(10)), Some(Vec2::new(1.0, 0.5)));
        assert_eq!(m.position(TagId(30)), Some(Vec2::new(3.0, 0.5)));
        for miss in [0, 15, 25, 31, u64::MAX] {
            assert_eq!(m.position(TagId(miss)), None);
            assert!(!m.contains(TagId(miss)));
        }
        let ids: Vec<u64> = m.iter().map(|(id, _)| id.0).collect();
        assert_eq!(ids, [10, 20, 30]);
    }

    #[test]
    fn duplicates_refused_and_map_unchanged() {
        let mut m = TagMap::<4>::default();
        m.insert(TagId(5), Vec2::new(1.0, 2.0)).unwrap();
        assert_eq!(
            m.insert(TagId(5), Vec2::new(9.0, 9.0)),
            Err(TagMapError::DuplicateId)
        );
        assert_eq!(m.position(TagId(5)), Some(Vec2::new(1.0, 2.0)));
        assert_eq!(m.len(), 1);
    }

    /// `push` builds the map `insert` builds from the same increasing ids,
    /// and refuses what `insert` refuses, an id below the last too,
    /// leaving the map unchanged.
    #[test]
    fn push_appends_increasing_ids_only() {
        let mut pushed = TagMap::<3>::new();
        let mut inserted = TagMap::<3>::new();
        for (id, x) in [(3, 0.5), (9, 1.5), (0x12_3456_789A, -2.0)] {
            pushed.push(TagId(id), Vec2::new(x, -x)).unwrap();
            inserted.insert(TagId(id), Vec2::new(x, -x)).unwrap();
        }
        assert_eq!(pushed, inserted);
        let mut m = TagMap::<3>::new();
        m.push(TagId(5), Vec2::ZERO).unwrap();
        assert_eq!(m.push(TagId(5), Vec2::ZERO), Err(TagMapError::DuplicateId));
        assert_eq!(m.push(TagId(4), Vec2::ZERO), Err(TagMapError::Unsorted));
        assert_eq!(
            m.push(TagId(6), Vec2::new(f32::NAN, 0.0)),
            Err(TagMapError::NonFinitePosition)
        );
        m.push(TagId(6), Vec2::ZERO).unwrap();
        m.push(TagId(7), Vec2::ZERO).unwrap();
        assert_eq!(m.push(TagId(8), Vec2::ZERO), Err(TagMapError::Full));
        assert_eq!(m.len(), 3);
        assert_eq!(m.position(TagId(5)), Some(Vec2::ZERO));
    }

    #[test]
    fn clear_empties_the_map_for_reuse() {
        let mut m = TagMap::<2>::new();
        m.insert(TagId(1), Vec2::ZERO).unwrap();
        m.insert(TagId(2), Vec2::ZERO).unwrap();
        m.clear();
        assert!(m.is_empty());
        assert_eq!(m.position(TagId(1)), None);
        m.insert(TagId(2), Vec2::new(1.0, 1.0)).unwrap();
        m.insert(TagId(1), Vec2::ZERO).unwrap();
        assert_eq!(m.position(TagId(2)), Some(Vec2::new(1.0, 1.0)));
    }

    #[test]
    fn full_refused() {
        let mut m = TagMap::<2>::new();
        m.insert(TagId(1), Vec2::ZERO).unwrap();
        m.insert(TagId(2), Vec2::ZERO).unwrap();
        assert_eq!(m.insert(TagId(3), Vec2::ZERO), Err(TagMapError::Full));
        assert_eq!(m.insert(TagId(0), Vec2::ZERO), Err(TagMapError::Full));
        // A duplicate in a full map is reported as a duplicate.
        assert_eq!(
            m.insert(TagId(1), Vec2::ZERO),
            Err(TagMapError::DuplicateId)
        );
        assert_eq!(m.len(), 2);
        let mut empty = TagMap::<0>::new();
        assert_eq!(empty.insert(TagId(1), Vec2::ZERO), Err(TagMapError::Full));
    }

    #[test]
    fn non_finite_refused() {
        let mut m = TagMap::<4>::new();
        for p in [
            Vec2::new(f32::NAN, 0.0),
            Vec2::new(0.0, f32::INFINITY),
            Vec2::new(f32::NEG_INFINITY, 1.0),
        ] {
            assert_eq!(m.insert(TagId(1), p), Err(TagMapError::NonFinitePosition));
        }
        assert!(m.is_empty());
    }

    proptest! {
        /// Same answers as a `BTreeMap` for any insert sequence and lookups.
        #[test]
        fn behaves_like_a_btree_map(
            inserts in prop::collection::vec((0_u64..64, -10.0_f32..10.0), 0..40),
            lookups in prop::collection::vec(0_u64..64, 0..40),
        ) {
            let mut m = TagMap::<16>::new();
            let mut model = BTreeMap::new();
            for (id, x) in inserts {
                let r = m.insert(TagId(id), Vec2::new(x, -x));
                let want = if model.contains_key(&id) {
                    Err(TagMapError::DuplicateId)
                } else if model.len() == 16 {
                    Err(TagMapError::Full)
                } else {
                    model.insert(id, Vec2::new(x, -x));
                    Ok(())
                };
                prop_assert_eq!(r, want);
            }
            for id in lookups {
                prop_assert_eq!(m.position(TagId(id)), model.get(&id).copied());
            }
            let all: Vec<(TagId, Vec2)> = m.iter().collect();
            let want: Vec<(TagId, Vec2)> = model.iter().map(|(&k, &v)| (TagId(k), v)).collect();
            prop_assert_eq!(all, want);
        }
    }
}
