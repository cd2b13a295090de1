//! Whether a recorder's world is still there. Its liveliness events say when it comes and goes,
//! but they are not ordered with a subscription's first look at who is present (Zenoh replays a
//! token it already knew on a task of its own, which may run after the token's deletion): a world
//! that died as the recorder came could seem present forever. So a world silent for a while is
//! asked after (who is present, by tokens), and taken for gone on two answers in a row without
//! it and nothing heard from it in between: one answer may be cut short on a busy link, and a
//! lockstep world may be silent for seconds while it waits for a slow agent. A world whose token
//! went is given a grace for its `End` (`EndGrace`), by the agents and the planner. Times are
//! inputs: instants on the role's monotonic clock.

use std::time::Duration;

use crate::time::Moment;

/// How long the world may be silent before the recorder asks whether it is still there, and how
/// often it asks again, in seconds.
pub const SILENCE_S: f64 = 5.0;

pub struct WorldWatch {
    seen: bool,
    left: Option<Moment>,
    /// The world's last message, its token's arrival, or the last question about it.
    quiet_since: Moment,
    /// The last answer was without the world, and nothing came from it since.
    doubted: bool,
}

impl WorldWatch {
    pub fn new(now: Moment) -> WorldWatch {
        WorldWatch {
            seen: false,
            left: None,
            quiet_since: now,
            doubted: false,
        }
    }

    /// The world's token came (`alive`) or went.
    pub fn on_presence(&mut self, alive: bool, now: Moment) {
        self.seen |= alive;
        self.left = (!alive).then_some(now);
        self.heard(now);
    }

    /// A message from the world.
    pub fn heard(&mut self, now: Moment) {
        self.quiet_since = now;
        self.doubted = false;
    }

    /// When to ask whether the world is there, if at all: it is believed present and has been
    /// silent for `SILENCE`.
    pub fn ask_at(&self) -> Option<Moment> {
        (self.seen && self.left.is_none()).then_some(self.quiet_since + SILENCE_S)
    }

    /// The answer to that question: whether the world's token is among those present, or `None`
    /// when the question failed (which says nothing).
    pub fn on_answer(&mut self, there: Option<bool>, now: Moment) {
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
    pub fn left(&self) -> Option<Moment> {
        self.left
    }
}

/// A world whose token went may have its `End` still on the way: the two travel apart, and the
/// End may come after. What waits for it (an agent, the planner) gives it `grace`, and takes the
/// world as gone without one only then: an end says the run is over, its absence that the world
/// is.
pub struct EndGrace {
    grace: Duration,
    /// When the world's token went, while its End is awaited.
    left_at: Option<Moment>,
}

impl EndGrace {
    pub fn new(grace: Duration) -> EndGrace {
        EndGrace { grace, left_at: None }
    }

    /// The world's token went at `now`.
    pub fn left(&mut self, now: Moment) {
        self.left_at.get_or_insert(now);
    }

    /// The world's token came again: it was a link that dropped, not the world leaving.
    pub fn back(&mut self) {
        self.left_at = None;
    }

    /// Whether the world's token has gone, and its End is awaited.
    pub fn waiting(&self) -> bool {
        self.left_at.is_some()
    }

    /// When the grace runs out, if one runs.
    pub fn poll_timeout(&self) -> Option<Moment> {
        self.left_at.map(|left| left + self.grace)
    }

    /// Whether at `now` a world gone for the grace without an End is gone for good.
    pub fn handle_timeout(&self, now: Moment) -> bool {
        self.poll_timeout().is_some_and(|due| now >= due)
    }
}

/// How long a recorder waits, after the world's end or after the world left without one, for a
/// tick that does not come whole, in seconds.
pub const END_STALL_S: f64 = 5.0;

/// How long a recorder that stopped for another reason than a signal waits for the roles' exit
/// reports, which they send as they exit, just after the end, in seconds.
pub const REPORTS_GRACE_S: f64 = 2.0;

/// What a recorder's wait found due.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Due {
    /// Ask who is present: the world has been silent a while.
    Ask,
    /// No world came within the startup timeout.
    NoWorld,
    /// The world ended or left, and no tick was written for `END_STALL_S`; in realtime, the
    /// world has been gone that long.
    Stalled,
    /// The recording stopped `REPORTS_GRACE_S` ago, and the reports still missing will not come.
    ReportsLate,
}

/// Every wait of `tcpf record`, as one machine: for a world to come (within the startup
/// timeout), whether a silent one is still there (`WorldWatch`), and for the last ticks once it
/// ended or left. A realtime recording goes on sampling without a world, so there only the
/// world's absence counts. Times are inputs.
pub struct RecorderWaits {
    world: WorldWatch,
    give_up_at: Moment,
    realtime: bool,
    /// When the last tick was written (or the recording started).
    progress: Moment,
    ended: bool,
    /// A question about the world is out: not asked again until it is answered.
    asking: bool,
    /// Once the recording has stopped: until when the exit reports may come.
    reports_due: Option<Moment>,
}

impl RecorderWaits {
    pub fn new(now: Moment, startup_timeout_s: f64, realtime: bool) -> RecorderWaits {
        RecorderWaits {
            world: WorldWatch::new(now),
            give_up_at: now + startup_timeout_s,
            realtime,
            progress: now,
            ended: false,
            asking: false,
            reports_due: None,
        }
    }

    /// The recording has stopped: from now on only the exit reports are waited for.
    pub fn closing(&mut self, now: Moment) {
        self.reports_due = Some(now + REPORTS_GRACE_S);
    }

    pub fn on_presence(&mut self, alive: bool, now: Moment) {
        self.world.on_presence(alive, now);
    }

    /// A message from the world.
    pub fn heard(&mut self, now: Moment) {
        self.world.heard(now);
    }

    /// A tick was written.
    pub fn progressed(&mut self, now: Moment) {
        self.progress = now;
    }

    /// The world's end came.
    pub fn ended(&mut self) {
        self.ended = true;
    }

    /// The answer to the question `Due::Ask` called for (see `WorldWatch::on_answer`).
    pub fn on_answer(&mut self, there: Option<bool>, now: Moment) {
        self.asking = false;
        self.world.on_answer(there, now);
    }

    pub fn left(&self) -> Option<Moment> {
        self.world.left()
    }

    /// Whether the world's token has been seen, so that its leaving means something.
    pub fn seen(&self) -> bool {
        self.world.seen()
    }

    fn stall_at(&self) -> Option<Moment> {
        match self.world.left() {
            Some(left) if self.realtime => Some(left + END_STALL_S),
            left => (self.ended || left.is_some()).then_some(self.progress + END_STALL_S),
        }
    }

    pub fn poll_timeout(&self) -> Option<Moment> {
        if self.reports_due.is_some() {
            return self.reports_due;
        }
        let give_up = (!self.world.seen()).then_some(self.give_up_at);
        let ask = self.world.ask_at().filter(|_| !self.asking);
        [give_up, ask, self.stall_at()]
            .into_iter()
            .flatten()
            .reduce(Moment::min)
    }

    /// What is due at `now`, if anything; `Ask` marks the question as out.
    pub fn handle_timeout(&mut self, now: Moment) -> Option<Due> {
        if let Some(due) = self.reports_due {
            return (now >= due).then_some(Due::ReportsLate);
        }
        if !self.world.seen() && now >= self.give_up_at {
            return Some(Due::NoWorld);
        }
        if self.stall_at().is_some_and(|at| now >= at) {
            return Some(Due::Stalled);
        }
        if !self.asking && self.world.ask_at().is_some_and(|at| now >= at) {
            self.asking = true;
            return Some(Due::Ask);
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(s: f64) -> Moment {
        Moment::from_secs(s)
    }

    #[test]
    fn a_silent_world_is_gone_after_two_answers_without_it() {
        let at = |s: u64| Moment::from_secs(s as f64);
        let mut watch = WorldWatch::new(at(0));
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
        let at = |s: u64| Moment::from_secs(s as f64);
        let mut watch = WorldWatch::new(at(0));
        watch.on_presence(true, at(0));
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

    #[test]
    fn a_recorder_gives_up_on_a_world_that_never_comes() {
        let mut waits = RecorderWaits::new(at(0.0), 60.0, false);
        assert_eq!(waits.poll_timeout(), Some(at(60.0)));
        assert_eq!(waits.handle_timeout(at(59.0)), None);
        assert_eq!(waits.handle_timeout(at(60.0)), Some(Due::NoWorld));
        waits.on_presence(true, at(61.0));
        assert_eq!(
            waits.handle_timeout(at(61.0)),
            None,
            "it came, late but before the look"
        );
    }

    #[test]
    fn a_recorder_asks_after_a_silent_world_once_at_a_time() {
        let mut waits = RecorderWaits::new(at(0.0), 60.0, false);
        waits.on_presence(true, at(1.0));
        assert_eq!(waits.poll_timeout(), Some(at(1.0) + SILENCE_S));
        assert_eq!(waits.handle_timeout(at(6.0)), Some(Due::Ask));
        assert_eq!(waits.poll_timeout(), None, "not asked again while the question is out");
        assert_eq!(waits.handle_timeout(at(30.0)), None);
        waits.progressed(at(10.0));
        waits.on_answer(Some(false), at(7.0));
        assert_eq!(waits.handle_timeout(at(12.0)), Some(Due::Ask));
        waits.on_answer(Some(false), at(12.0));
        assert_eq!(waits.left(), Some(at(12.0)));
        assert_eq!(
            waits.poll_timeout(),
            Some(at(10.0) + END_STALL_S),
            "then the last ticks are waited for, from the last one written"
        );
        assert_eq!(waits.handle_timeout(at(15.0)), Some(Due::Stalled));
    }

    #[test]
    fn after_the_end_a_recorder_waits_for_the_last_ticks_from_the_last_one_written() {
        let mut lockstep = RecorderWaits::new(at(0.0), 60.0, false);
        lockstep.on_presence(true, at(0.0));
        lockstep.heard(at(4.0));
        lockstep.progressed(at(4.0));
        lockstep.ended();
        assert_eq!(lockstep.poll_timeout(), Some(at(4.0) + END_STALL_S));
        lockstep.heard(at(6.0));
        lockstep.progressed(at(6.0));
        assert_eq!(lockstep.handle_timeout(at(9.0)), None, "a tick written since");
        assert_eq!(lockstep.handle_timeout(at(11.0)), Some(Due::Stalled));
        // Realtime samples on without the world: only how long it has been gone counts.
        let mut realtime = RecorderWaits::new(at(0.0), 60.0, true);
        realtime.on_presence(true, at(0.0));
        realtime.on_presence(false, at(20.0));
        realtime.progressed(at(24.0));
        assert_eq!(realtime.poll_timeout(), Some(at(20.0) + END_STALL_S));
        assert_eq!(realtime.handle_timeout(at(25.0)), Some(Due::Stalled));
    }

    /// Once the recording has stopped, only the exit reports are waited for, and only
    /// `REPORTS_GRACE_S`: a silent world is not asked after, nor a stall said.
    #[test]
    fn a_stopped_recording_waits_for_the_reports_a_while() {
        let mut waits = RecorderWaits::new(at(0.0), 60.0, false);
        waits.on_presence(true, at(0.0));
        waits.ended();
        waits.closing(at(1.0));
        assert_eq!(waits.poll_timeout(), Some(at(1.0) + REPORTS_GRACE_S));
        assert_eq!(waits.handle_timeout(at(2.9)), None);
        assert_eq!(waits.handle_timeout(at(1.0) + REPORTS_GRACE_S), Some(Due::ReportsLate));
        assert_eq!(waits.handle_timeout(at(60.0)), Some(Due::ReportsLate), "not a stall");
    }

    #[test]
    fn an_end_is_awaited_for_the_grace_after_the_world_left() {
        let mut grace = EndGrace::new(Duration::from_millis(500));
        assert_eq!(grace.poll_timeout(), None, "nothing awaited while the world is there");
        grace.left(at(10.0));
        grace.left(at(10.2));
        assert_eq!(grace.poll_timeout(), Some(at(10.5)), "from the first time it went");
        assert!(grace.waiting() && !grace.handle_timeout(at(10.4)));
        assert!(grace.handle_timeout(at(10.5)));
        grace.back();
        assert!(
            !grace.waiting() && !grace.handle_timeout(at(11.0)),
            "a world back is not gone"
        );
    }
}
