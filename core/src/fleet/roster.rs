//! Where a vehicle's id sits in the fleet's order: what the world, the recorder and the metrics
//! look up for every message, so a lookup must not cost a scan of the fleet.

/// The fleet's ids in their order, and sorted, for lookups in O(log N). Ids are unique (the
/// mission is validated).
#[derive(Debug, Clone)]
pub struct Roster {
    ids: Vec<u32>,
    sorted: Vec<(u32, usize)>,
}

impl Roster {
    pub fn new(ids: &[u32]) -> Roster {
        let mut sorted: Vec<(u32, usize)> = ids.iter().enumerate().map(|(n, &id)| (id, n)).collect();
        sorted.sort_unstable();
        Roster {
            ids: ids.to_vec(),
            sorted,
        }
    }

    /// The position of `id` in the fleet's order.
    pub fn position(&self, id: u32) -> Option<usize> {
        // A fleet numbered on from its first id, as missions are, holds `id` at its offset from
        // the first: found without a search (ids are unique, so a match there is the one).
        let offset = id.wrapping_sub(*self.ids.first()?) as usize;
        if self.ids.get(offset) == Some(&id) {
            return Some(offset);
        }
        self.sorted
            .binary_search_by_key(&id, |&(i, _)| i)
            .ok()
            .map(|k| self.sorted[k].1)
    }

    pub fn ids(&self) -> &[u32] {
        &self.ids
    }

    pub fn len(&self) -> usize {
        self.ids.len()
    }

    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_position_is_the_index_in_the_fleets_order() {
        let ids = [7, 3, 12, 1, 40];
        let roster = Roster::new(&ids);
        for (n, &id) in ids.iter().enumerate() {
            assert_eq!(roster.position(id), Some(n));
        }
        assert_eq!(roster.position(2), None);
        let numbered = Roster::new(&[4, 5, 6, 9]);
        for (n, id) in [4, 5, 6, 9].into_iter().enumerate() {
            assert_eq!(numbered.position(id), Some(n));
        }
        assert_eq!(numbered.position(7), None);
        assert_eq!(numbered.position(3), None);
        assert_eq!(Roster::new(&[]).position(1), None);
        // At the offset sits another id: found by the search.
        let unsorted = Roster::new(&[2, 1, 3]);
        assert_eq!(unsorted.position(3), Some(2));
        assert_eq!(unsorted.position(1), Some(1));
        let wrapping = Roster::new(&[u32::MAX, 0]);
        assert_eq!(wrapping.position(0), Some(1));
        assert_eq!(wrapping.position(u32::MAX), Some(0));
        assert_eq!(roster.ids(), &ids);
    }
}
