//! Who is present, by liveliness changes alone, for a role that has followed them since before
//! anyone it asks about could leave (the world follows its fleet from its start, so at the end
//! it knows who is still there without asking the router).
//!
//! A count per process name, not a set: Zenoh replays a token the session already knew on a task
//! of its own, which may run after the token's deletion, so a coming and a going of the same
//! token may arrive in either order and must still cancel; and a process started again may come
//! before its predecessor's token has gone.

use std::collections::BTreeMap;

#[derive(Debug, Clone)]
pub struct Present<K> {
    /// Tokens come less tokens gone, per name; a name at zero is not kept.
    tokens: BTreeMap<K, i64>,
}

impl<K> Default for Present<K> {
    fn default() -> Self {
        Present {
            tokens: BTreeMap::new(),
        }
    }
}

impl<K: Ord> Present<K> {
    /// A token of `who` came (`alive`) or went.
    pub fn on_change(&mut self, who: K, alive: bool) {
        let count = self.tokens.entry(who).or_default();
        *count += if alive { 1 } else { -1 };
        self.tokens.retain(|_, n| *n != 0);
    }

    /// Whether someone `matching` is present: more of its tokens came than went.
    pub fn any(&self, matching: impl Fn(&K) -> bool) -> bool {
        self.tokens.iter().any(|(who, &n)| n > 0 && matching(who))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_token_that_came_and_went_is_gone_in_either_order() {
        let mut present = Present::default();
        present.on_change(("agent", 1), true);
        present.on_change(("agent", 2), true);
        assert!(present.any(|(role, _)| *role == "agent"));
        present.on_change(("agent", 1), false);
        assert!(present.any(|who| *who == ("agent", 2)));
        assert!(!present.any(|who| *who == ("agent", 1)));
        // Its deletion first, then the replay of the token the session knew.
        present.on_change(("agent", 2), false);
        assert!(!present.any(|(role, _)| *role == "agent"));
        present.on_change(("agent", 3), false);
        present.on_change(("agent", 3), true);
        assert!(!present.any(|(role, _)| *role == "agent"));
        assert!(present.tokens.is_empty());
    }

    #[test]
    fn a_process_started_again_before_its_predecessor_left_stays_present() {
        let mut present = Present::default();
        present.on_change(("agent", 1), true);
        present.on_change(("agent", 1), true);
        present.on_change(("agent", 1), false);
        assert!(present.any(|who| *who == ("agent", 1)));
        present.on_change(("world", 0), true);
        assert!(!present.any(|(role, _)| *role == "recorder"));
        present.on_change(("agent", 1), false);
        assert!(!present.any(|(role, _)| *role == "agent"));
        assert!(present.any(|(role, _)| *role == "world"));
    }
}
