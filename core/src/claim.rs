//! Who holds a role that only one process of a fleet may hold (the world, the agent of a
//! vehicle) when several claim it at once. A claimant announces its claim, waits for every claim
//! made before its own to reach it, then looks at all of them: the earliest holds the role, and
//! everyone else steps back. Looking before announcing, as a role once did, let two processes
//! that started together each find nobody and both drive the fleet.
//!
//! Why the earliest and not the first one seen: two claimants may see different sets (one looks
//! before the other's claim arrives), but a claim it could not see was made after it looked, so
//! a full settling time after its own, and that later claimant sees the earlier claim and steps
//! back. Both then agree. Times are the claimants' wall clocks, so hosts' clocks must agree to
//! within the settling time (docs/TESTBED.md asks for NTP or PTP anyway); equal times fall to the
//! lesser session id, which every claimant reads the same.

use std::fmt;

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

/// What a claimant learns from the claims it sees once its own has settled.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    Holds,
    /// Another claimed the role at about the same time, and earlier: it is alive, and it holds
    /// the role. Waiting would be wrong: a run that is over in a second lets its claim go, and
    /// the loser would then start a second one.
    Lost(Claim),
    /// Another held the role before this claimant came. It may be a process that has just
    /// stopped, whose claim lingers until the router hears its connection close (an agent
    /// started again at once after it died): look again until that would have happened.
    HeldBy(Claim),
    /// Its own claim is not among those seen: the answer is from before it reached the others,
    /// and says nothing yet.
    Unseen,
}

/// The outcome for `mine` among the claims `seen` (its own included), claims made within
/// `settle_ns` of each other being contemporaries.
pub fn outcome(mine: &Claim, seen: &[Claim], settle_ns: u64) -> Outcome {
    if !seen.contains(mine) {
        return Outcome::Unseen;
    }
    match seen.iter().min() {
        Some(first) if first.since_ns.saturating_add(settle_ns) < mine.since_ns => Outcome::HeldBy(first.clone()),
        Some(first) if first != mine => Outcome::Lost(first.clone()),
        _ => Outcome::Holds,
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

    #[test]
    fn the_earliest_claim_holds_and_every_claimant_agrees_whatever_it_saw() {
        let (a, b, c) = (claim(100, "a1"), claim(250, "0f"), claim(300, "ff"));
        // Each sees a different subset, always with its own; all name `a`.
        assert_eq!(
            outcome(&a, std::slice::from_ref(&a), SETTLE),
            Outcome::Holds,
            "a looked before the others came"
        );
        assert_eq!(outcome(&b, &[b.clone(), a.clone()], SETTLE), Outcome::Lost(a.clone()));
        assert_eq!(
            outcome(&c, &[c.clone(), b.clone(), a.clone()], SETTLE),
            Outcome::Lost(a.clone())
        );
        // Claims made in the same nanosecond: the lesser session id, for both.
        let (x, y) = (claim(7, "1a"), claim(7, "1b"));
        assert_eq!(outcome(&x, &[y.clone(), x.clone()], SETTLE), Outcome::Holds);
        assert_eq!(outcome(&y, &[x.clone(), y.clone()], SETTLE), Outcome::Lost(x.clone()));
    }

    #[test]
    fn a_claim_older_than_the_settling_time_is_a_holder_that_may_have_just_stopped() {
        let (old, new) = (claim(100, "a1"), claim(100 + SETTLE + 1, "0f"));
        assert_eq!(
            outcome(&new, &[old.clone(), new.clone()], SETTLE),
            Outcome::HeldBy(old.clone())
        );
        let contemporary = claim(100 + SETTLE, "0f");
        assert_eq!(
            outcome(&contemporary, &[old.clone(), contemporary.clone()], SETTLE),
            Outcome::Lost(old)
        );
        assert_eq!(
            outcome(&new, std::slice::from_ref(&new), SETTLE),
            Outcome::Holds,
            "its claim went: the role is free"
        );
    }

    #[test]
    fn an_answer_without_ones_own_claim_decides_nothing() {
        let (a, b) = (claim(100, "a1"), claim(250, "0f"));
        assert_eq!(outcome(&b, &[], SETTLE), Outcome::Unseen);
        assert_eq!(outcome(&b, &[a], SETTLE), Outcome::Unseen);
    }

    #[test]
    fn a_claim_reads_back_from_its_key_chunk_and_sorts_as_its_chunk_does() {
        let c = claim(1_795_000_000_123_456_789, "8e2a61f0c3");
        assert_eq!(c.chunk(), "01795000000123456789-8e2a61f0c3");
        assert_eq!(Claim::parse(&c.chunk()), Some(c.clone()));
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
}
