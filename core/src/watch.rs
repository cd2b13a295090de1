//! Whether a recorder's world is still there. Its liveliness events say when it comes and goes,
//! but they are not ordered with a subscription's first look at who is present (Zenoh replays a
//! token it already knew on a task of its own, which may run after the token's deletion): a world
//! that died as the recorder came could seem present forever. So a world silent for a while is
//! asked after (who is present, by tokens), and taken for gone on two answers in a row without
//! it and nothing heard from it in between: one answer may be cut short on a busy link, and a
//! lockstep world may be silent for seconds while it waits for a slow agent. Times are inputs:
//! seconds on the recorder's monotonic clock.

/// How long the world may be silent before the recorder asks whether it is still there, and how
/// often it asks again, in seconds.
pub const SILENCE_S: f64 = 5.0;

pub struct WorldWatch {
    seen: bool,
    left: Option<f64>,
    /// The world's last message, its token's arrival, or the last question about it.
    quiet_since: f64,
    /// The last answer was without the world, and nothing came from it since.
    doubted: bool,
}

impl WorldWatch {
    pub fn new(now: f64) -> WorldWatch {
        WorldWatch {
            seen: false,
            left: None,
            quiet_since: now,
            doubted: false,
        }
    }

    /// The world's token came (`alive`) or went.
    pub fn on_presence(&mut self, alive: bool, now: f64) {
        self.seen |= alive;
        self.left = (!alive).then_some(now);
        self.heard(now);
    }

    /// A message from the world.
    pub fn heard(&mut self, now: f64) {
        self.quiet_since = now;
        self.doubted = false;
    }

    /// When to ask whether the world is there, if at all: it is believed present and has been
    /// silent for `SILENCE`.
    pub fn ask_at(&self) -> Option<f64> {
        (self.seen && self.left.is_none()).then_some(self.quiet_since + SILENCE_S)
    }

    /// The answer to that question: whether the world's token is among those present, or `None`
    /// when the question failed (which says nothing).
    pub fn on_answer(&mut self, there: Option<bool>, now: f64) {
        match there {
            Some(true) => self.heard(now),
            Some(false) if self.doubted => self.left = Some(now),
            Some(false) => {
                self.doubted = true;
                self.quiet_since = now;
            }
            None => self.quiet_since = now,
        }
    }

    pub fn seen(&self) -> bool {
        self.seen
    }

    /// When the world was found gone, if it was.
    pub fn left(&self) -> Option<f64> {
        self.left
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_silent_world_is_gone_after_two_answers_without_it() {
        let at = |s: u64| s as f64;
        let mut watch = WorldWatch::new(0.0);
        assert_eq!(watch.ask_at(), None, "nothing to ask before the world came");
        watch.on_presence(true, at(1));
        assert_eq!(watch.ask_at(), Some(at(6)));
        watch.heard(at(4));
        assert_eq!(watch.ask_at(), Some(at(9)), "a message puts the question off");
        watch.on_answer(Some(false), at(9));
        assert_eq!(watch.left(), None, "one answer without it may be cut short");
        assert_eq!(watch.ask_at(), Some(at(14)));
        watch.on_answer(Some(false), at(14));
        assert_eq!(watch.left(), Some(at(14)));
        assert_eq!(watch.ask_at(), None);
        watch.on_presence(true, at(15));
        assert_eq!(watch.left(), None, "a world that comes back is there");
    }

    #[test]
    fn what_comes_between_two_answers_without_the_world_keeps_it() {
        let at = |s: u64| s as f64;
        let mut watch = WorldWatch::new(0.0);
        watch.on_presence(true, 0.0);
        watch.on_answer(Some(false), at(5));
        watch.heard(at(7));
        watch.on_answer(Some(false), at(12));
        assert_eq!(watch.left(), None, "a message came in between");
        watch.on_answer(Some(true), at(17));
        watch.on_answer(Some(false), at(22));
        assert_eq!(watch.left(), None, "and so did an answer with it");
        watch.on_answer(None, at(27));
        assert_eq!(watch.ask_at(), Some(at(32)), "a failed question is asked again later");
        watch.on_answer(Some(false), at(32));
        assert_eq!(watch.left(), Some(at(32)), "it says nothing either way");
        watch.on_presence(false, at(33));
        assert_eq!(watch.left(), Some(at(33)), "its token's going is enough");
    }
}
