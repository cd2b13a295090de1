//! Who holds a role that only one process of a fleet may hold (the world, the agent of a
//! vehicle) when several claim it at once. A claimant announces its claim, then looks at every
//! claim of the role: the one that holds it says so with a second mark, and everyone else steps
//! back. Looking before announcing, as a role once did, let two processes that started together
//! each find nobody and both drive the fleet.
//!
//! Claimants that meet at one router decide as soon as the facts are in (`Claimant`); peers,
//! which may not have met yet, wait for a contemporary's claim to reach them, then the earliest
//! holds. Why the earliest and not the first one seen: two claimants may see different sets (one
//! looks before the other's claim arrives), but a claim it could not see was made after it
//! looked, so a full settling time after its own, and that later claimant sees the earlier claim
//! and steps back. Both then agree. Times are the claimants' wall clocks, so hosts' clocks must
//! agree to within the settling time (docs/TESTBED.md asks for NTP or PTP anyway); equal times
//! fall to the lesser session id, which every claimant reads the same.

use std::fmt;
use std::time::Duration;

use crate::roles::machine::Machine;
use crate::time::Moment;

/// What a holder's mark adds to its claim's chunk.
const HELD: &str = "-held";

/// One process's claim: when it made it (nanoseconds since the Unix epoch, on its own clock) and
/// the id of its session, which names it to whoever is refused.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct Claim {
    pub since_ns: u64,
    pub session: String,
}

impl Claim {
    /// The claim as the last chunk of a key: fixed-width time first, so keys sort as claims do.
    pub fn chunk(&self) -> String {
        format!("{:020}-{}", self.since_ns, self.session)
    }

    /// The mark of a claimant that holds the role, beside its claim: the claim's chunk, marked.
    pub fn held_chunk(&self) -> String {
        format!("{}{HELD}", self.chunk())
    }

    /// A claim or a holder's mark (`true`) from its key's last chunk.
    pub fn parse_marked(chunk: &str) -> Option<(Claim, bool)> {
        match chunk.strip_suffix(HELD) {
            Some(claim) => Some((Claim::parse(claim)?, true)),
            None => Some((Claim::parse(chunk)?, false)),
        }
    }

    pub fn parse(chunk: &str) -> Option<Claim> {
        let (since, session) = chunk.split_once('-')?;
        let valid = since.len() == 20 && !session.is_empty() && session.bytes().all(|b| b.is_ascii_hexdigit());
        Some(Claim {
            since_ns: since.parse().ok().filter(|_| valid)?,
            session: session.to_string(),
        })
    }
}

impl fmt::Display for Claim {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.since_ns / 1_000_000_000;
        let (h, m, s) = (s / 3600 % 24, s / 60 % 60, s % 60);
        write!(f, "session {} (claimed at {h:02}:{m:02}:{s:02} UTC)", self.session)
    }
}

/// What a claimant learns from the claims it sees.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    Holds,
    /// Another claimed the role at about the same time and is alive: it claimed earlier, or it
    /// already holds the role. Waiting would be wrong: a run that is over in a second lets its
    /// claim go, and the loser would then start a second one.
    Lost(Claim),
    /// Another held the role before this claimant came. It may be a process that has just
    /// stopped, whose claim lingers until the router hears its connection close (an agent
    /// started again at once after it died): look again until that would have happened.
    HeldBy(Claim),
    /// Its own claim is not among those seen: the answer is from before it reached the others,
    /// and says nothing yet.
    Unseen,
    /// This claim is the earliest, but later ones are there that have not stepped back, and one
    /// of them may have looked before this one arrived and found itself alone (`Claimant`):
    /// wait until each has gone or one holds.
    Contested,
}

/// A claimant's look at the claims of its role, as the router shows them, and the marks of those
/// that hold it.
///
/// How soon it may decide depends on who can be claiming. Started beside others that meet at
/// one router (`patient`), it decides as soon as the facts are in: the router answers one
/// client's declarations and questions in the order it sent them, so a claimant that sees no
/// other at its look holds at once, and a later claim it did not see looked after this one's
/// claim was at the router, saw it, and steps back; only the earliest of several that saw each
/// other waits, and only for the later ones to step back, or for one that found itself alone to
/// say it holds. Otherwise (peers, which may not have met yet) it looks only once a
/// contemporary's claim has had `contemporaries_ns` to reach it, and the earliest holds.
#[derive(Debug, Clone)]
pub struct Claimant {
    mine: Claim,
    /// Every claim seen, and whether its claimant says it holds the role.
    seen: std::collections::BTreeMap<Claim, bool>,
    contemporaries_ns: u64,
    patient: bool,
}

impl Claimant {
    pub fn new(mine: Claim, contemporaries_ns: u64, patient: bool) -> Claimant {
        Claimant {
            mine,
            seen: Default::default(),
            contemporaries_ns,
            patient,
        }
    }

    /// A claim the router shows; `held`: its holder's mark, not a claim of its own.
    pub fn saw(&mut self, claim: Claim, held: bool) {
        *self.seen.entry(claim).or_insert(false) |= held;
    }

    /// What the claims seen say now, claims made within `contemporaries_ns` of each other being
    /// contemporaries.
    pub fn outcome(&self) -> Outcome {
        if !self.seen.contains_key(&self.mine) {
            return Outcome::Unseen;
        }
        let old = |c: &Claim| c.since_ns.saturating_add(self.contemporaries_ns) < self.mine.since_ns;
        let others = || self.seen.iter().filter(|(c, _)| **c != self.mine);
        if let Some((holder, _)) = others().find(|(_, held)| **held) {
            let holder = holder.clone();
            return if old(&holder) {
                Outcome::HeldBy(holder)
            } else {
                Outcome::Lost(holder)
            };
        }
        match self.seen.keys().next() {
            Some(first) if old(first) => Outcome::HeldBy(first.clone()),
            Some(first) if *first != self.mine => Outcome::Lost(first.clone()),
            _ if self.patient && others().next().is_some() => Outcome::Contested,
            _ => Outcome::Holds,
        }
    }

    /// What is left to decide once every claim made before this one, and every later claimant's
    /// word, has had time to come: a contest is then the earliest's, as for peers.
    pub fn settled(&self) -> Outcome {
        match self.outcome() {
            Outcome::Contested => Outcome::Holds,
            decided => decided,
        }
    }
}

/// How long a claimant waits to look, and looks again.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClaimWaits {
    /// Before its first look: how long a contemporary's claim may take to reach it (peers that
    /// may not have met), or nothing (one router, or no rival).
    pub settle: Duration,
    /// How far apart two claims may be and still be contemporaries (`Claimant`).
    pub contemporaries: Duration,
    /// After the first look, how long an undecided claimant looks again: as long as the claim of
    /// a process just gone lingers at the router.
    pub linger: Duration,
    /// Between two looks.
    pub look_again: Duration,
}

/// A claimant's process (`tcpf_bus::claim`): it looks at the claims of its role once `settle`
/// has passed, and again while what it sees is undecided and `linger` has not, then says what
/// it settled on.
#[derive(Debug)]
pub struct Claiming {
    mine: Claim,
    patient: bool,
    waits: ClaimWaits,
    /// When the next look is due; `None` while one is under way.
    look_at: Option<Moment>,
    /// A look is due and not yet asked for.
    asking: bool,
    /// After the first look, the last at which it may still wait.
    last: Option<Moment>,
    settled: Option<Settled>,
}

/// What a claimant settled on.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Settled {
    Holds,
    /// Another holds the role, or claimed it first.
    Refused(Claim),
    /// The router never showed this claim, or a contest never ended, within the waits.
    Unsure,
}

/// A claimant's input: the claims the router showed at a look, each with whether it is a
/// holder's mark.
#[derive(Debug, Clone)]
pub struct Seen(pub Vec<(Claim, bool)>);

/// A claimant's output: look at the claims.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Look;

impl Claiming {
    /// `patient`: the claimants meet at one router (`Claimant`).
    pub fn new(mine: Claim, patient: bool, waits: ClaimWaits, now: Moment) -> Claiming {
        Claiming {
            mine,
            patient,
            waits,
            look_at: Some(now + waits.settle),
            asking: false,
            last: None,
            settled: None,
        }
    }
}

impl Machine for Claiming {
    type Input = Seen;
    type Output = Look;
    type Exit = Settled;

    fn handle(&mut self, Seen(claims): Seen, now: Moment) {
        let last = *self.last.get_or_insert(now + self.waits.linger);
        let mut claimant = Claimant::new(
            self.mine.clone(),
            self.waits.contemporaries.as_nanos() as u64,
            self.patient,
        );
        for (claim, held) in claims {
            claimant.saw(claim, held);
        }
        self.settled = match claimant.outcome() {
            Outcome::HeldBy(_) | Outcome::Unseen | Outcome::Contested if now < last => {
                self.look_at = Some(now + self.waits.look_again);
                return;
            }
            _ => Some(match claimant.settled() {
                Outcome::Holds => Settled::Holds,
                Outcome::Lost(holder) | Outcome::HeldBy(holder) => Settled::Refused(holder),
                Outcome::Unseen | Outcome::Contested => Settled::Unsure,
            }),
        };
    }

    fn poll_timeout(&self) -> Option<Moment> {
        self.look_at
    }

    fn handle_timeout(&mut self, now: Moment, _: Moment) {
        if self.look_at.is_some_and(|at| at <= now) {
            self.look_at = None;
            self.asking = true;
        }
    }

    fn poll_output(&mut self) -> Option<Look> {
        std::mem::take(&mut self.asking).then_some(Look)
    }

    fn poll_exit(&mut self) -> Option<Settled> {
        self.settled.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SETTLE: u64 = 1_500_000_000;

    fn claim(since_ns: u64, session: &str) -> Claim {
        Claim {
            since_ns,
            session: session.into(),
        }
    }

    /// What `mine` decides from `seen` (each claim and whether it is marked held).
    fn decide(mine: &Claim, seen: &[(&Claim, bool)], patient: bool) -> Outcome {
        look(mine, seen, patient).outcome()
    }

    fn look(mine: &Claim, seen: &[(&Claim, bool)], patient: bool) -> Claimant {
        let mut c = Claimant::new(mine.clone(), SETTLE, patient);
        for (claim, held) in seen {
            c.saw((*claim).clone(), *held);
        }
        c
    }

    #[test]
    fn the_earliest_claim_holds_and_every_claimant_agrees_whatever_it_saw() {
        let (a, b, c) = (claim(100, "a1"), claim(250, "0f"), claim(300, "ff"));
        // Each sees a different subset, always with its own; all name `a`.
        assert_eq!(
            decide(&a, &[(&a, false)], false),
            Outcome::Holds,
            "a looked before the others came"
        );
        assert_eq!(decide(&b, &[(&b, false), (&a, false)], false), Outcome::Lost(a.clone()));
        assert_eq!(
            decide(&c, &[(&c, false), (&b, false), (&a, false)], false),
            Outcome::Lost(a.clone())
        );
        // Claims made in the same nanosecond: the lesser session id, for both.
        let (x, y) = (claim(7, "1a"), claim(7, "1b"));
        assert_eq!(decide(&x, &[(&y, false), (&x, false)], false), Outcome::Holds);
        assert_eq!(decide(&y, &[(&x, false), (&y, false)], false), Outcome::Lost(x.clone()));
    }

    #[test]
    fn at_one_router_a_claimant_alone_at_its_look_holds_and_an_earlier_one_that_saw_it_waits_for_its_word() {
        // `b` claimed first by its clock, but `a`'s claim reached the router first and `a`
        // looked before `b`'s came: `a` holds at once, and says so.
        let (b, a) = (claim(100, "0f"), claim(150, "a1"));
        assert_eq!(decide(&a, &[(&a, false)], true), Outcome::Holds);
        assert_eq!(
            decide(&b, &[(&a, false), (&b, false)], true),
            Outcome::Contested,
            "a may have looked before b came"
        );
        assert_eq!(
            decide(&b, &[(&a, true), (&b, false)], true),
            Outcome::Lost(a.clone()),
            "it had: a holds"
        );
        // Had `a` seen `b`, it would have stepped back: its claim goes, and `b` holds.
        assert_eq!(decide(&a, &[(&a, false), (&b, false)], true), Outcome::Lost(b.clone()));
        assert_eq!(decide(&b, &[(&b, false)], true), Outcome::Holds);
        // A later claimant that never says a word: once it has had the time a peer is given,
        // the contest is the earliest's.
        assert_eq!(look(&b, &[(&b, false), (&a, false)], true).settled(), Outcome::Holds);
        // Peers never wait for a word: they looked late enough for every claim to be in.
        assert_eq!(decide(&b, &[(&a, false), (&b, false)], false), Outcome::Holds);
    }

    #[test]
    fn a_holders_mark_beats_an_earlier_claim() {
        let (early, holder) = (claim(100, "0f"), claim(200, "a1"));
        // A peer that looked after a claimant at one router held: the mark decides, not the time.
        assert_eq!(
            decide(&early, &[(&early, false), (&holder, true)], false),
            Outcome::Lost(holder.clone())
        );
        assert_eq!(
            decide(&early, &[(&early, false), (&holder, false)], true),
            Outcome::Contested,
            "its mark not yet seen"
        );
        // A mark of one's own is no rival.
        assert_eq!(decide(&early, &[(&early, true)], true), Outcome::Holds);
    }

    #[test]
    fn a_claim_older_than_the_settling_time_is_a_holder_that_may_have_just_stopped() {
        let (old, new) = (claim(100, "a1"), claim(100 + SETTLE + 1, "0f"));
        for patient in [false, true] {
            assert_eq!(
                decide(&new, &[(&old, false), (&new, false)], patient),
                Outcome::HeldBy(old.clone())
            );
            assert_eq!(
                decide(&new, &[(&old, true), (&new, false)], patient),
                Outcome::HeldBy(old.clone())
            );
            assert_eq!(
                decide(&new, &[(&new, false)], patient),
                Outcome::Holds,
                "its claim went: the role is free"
            );
        }
        let contemporary = claim(100 + SETTLE, "0f");
        assert_eq!(
            decide(&contemporary, &[(&old, false), (&contemporary, false)], false),
            Outcome::Lost(old)
        );
    }

    #[test]
    fn an_answer_without_ones_own_claim_decides_nothing() {
        let (a, b) = (claim(100, "a1"), claim(250, "0f"));
        assert_eq!(decide(&b, &[], true), Outcome::Unseen);
        assert_eq!(decide(&b, &[(&a, true)], false), Outcome::Unseen);
    }

    #[test]
    fn a_claim_reads_back_from_its_key_chunk_and_sorts_as_its_chunk_does() {
        let c = claim(1_795_000_000_123_456_789, "8e2a61f0c3");
        assert_eq!(c.chunk(), "01795000000123456789-8e2a61f0c3");
        assert_eq!(Claim::parse(&c.chunk()), Some(c.clone()));
        assert_eq!(Claim::parse_marked(&c.chunk()), Some((c.clone(), false)));
        assert_eq!(Claim::parse_marked(&c.held_chunk()), Some((c.clone(), true)));
        assert_eq!(Claim::parse(&c.held_chunk()), None, "a mark is no claim");
        let earlier = claim(999, "ff");
        assert!(earlier.chunk() < c.chunk() && earlier < c);
        for bad in [
            "",
            "-",
            "123-ab",
            "01795000000123456789-",
            "01795000000123456789-xyz",
            "abc",
        ] {
            assert_eq!(Claim::parse(bad), None, "{bad:?}");
        }
        assert_eq!(c.to_string(), "session 8e2a61f0c3 (claimed at 11:06:40 UTC)");
    }

    const WAITS: ClaimWaits = ClaimWaits {
        settle: Duration::ZERO,
        contemporaries: Duration::from_millis(1500),
        linger: Duration::from_secs(2),
        look_again: Duration::from_millis(20),
    };

    /// Runs `claiming` on a clock that jumps to each wake-up, the router answering each look
    /// at `t` with `shown(t)`: what it settled on, and when.
    fn settle(mut claiming: Claiming, shown: impl Fn(f64) -> Vec<(Claim, bool)>) -> (Settled, f64) {
        loop {
            let at = claiming.poll_timeout().expect("an undecided claimant waits for a look");
            claiming.handle_timeout(at, at);
            while claiming.poll_output().is_some() {
                claiming.handle(Seen(shown(at.secs())), at);
            }
            if let Some(settled) = claiming.poll_exit() {
                return (settled, at.secs());
            }
        }
    }

    #[test]
    fn a_claimant_looks_once_settled_and_again_until_the_facts_are_in() {
        let (old, mine) = (claim(100, "0a"), claim(SETTLE * 10, "0b"));
        let start = Moment::from_secs(5.0);

        // Alone at one router: it looks at once and holds.
        let claiming = Claiming::new(mine.clone(), true, WAITS, start);
        assert_eq!(claiming.poll_timeout(), Some(start));
        assert_eq!(settle(claiming, |_| vec![(mine.clone(), false)]), (Settled::Holds, 5.0));

        // A peer looks only once a contemporary's claim has had time to reach it.
        let peer = ClaimWaits {
            settle: Duration::from_millis(1500),
            ..WAITS
        };
        let claiming = Claiming::new(mine.clone(), false, peer, start);
        assert_eq!(claiming.poll_timeout(), Some(start + 1.5));
        assert_eq!(settle(claiming, |_| vec![(mine.clone(), false)]), (Settled::Holds, 6.5));

        // The claim of a holder just gone lingers: it looks every 20 ms until the claim goes.
        let mut claiming = Claiming::new(mine.clone(), true, WAITS, start);
        let lingering = |t: f64| {
            let mut shown = vec![(mine.clone(), false)];
            if t < 5.5 {
                shown.push((old.clone(), true));
            }
            shown
        };
        claiming.handle_timeout(start, start);
        assert_eq!(claiming.poll_output(), Some(Look));
        assert_eq!(claiming.poll_output(), None, "one look at a time");
        claiming.handle(Seen(lingering(5.0)), start);
        assert_eq!(claiming.poll_exit(), None);
        let (settled, at) = settle(claiming, lingering);
        assert_eq!(settled, Settled::Holds);
        assert!((5.5..5.53).contains(&at), "held at {at}");

        // A holder that stays is named once the claim of one just gone would have lingered.
        let claiming = Claiming::new(mine.clone(), true, WAITS, start);
        let (settled, at) = settle(claiming, |_| vec![(mine.clone(), false), (old.clone(), true)]);
        assert_eq!(settled, Settled::Refused(old.clone()));
        assert!((7.0..7.03).contains(&at), "refused at {at}");

        // A router that never shows the claim leaves it unsure, after as long.
        let claiming = Claiming::new(mine.clone(), true, WAITS, start);
        let (settled, at) = settle(claiming, |_| Vec::new());
        assert_eq!(settled, Settled::Unsure);
        assert!((7.0..7.03).contains(&at), "unsure at {at}");
    }
}
