//! Link models (MODEL D12, D21): each directed link j→i decides, at the receiver, whether the
//! message of each communication instant is lost and how long it travels, from a random stream of
//! its own and the distance between the vehicles when it was sent. The stream is keyed by
//! (mission seed, from, to) alone, so no other link and no ordering of events can change it.

pub mod modem;

use std::collections::BTreeMap;

use rand_chacha::rand_core::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

pub use crate::links::modem::Cause;
use crate::mission::{Mission, ModemConfig};

/// How a link loses messages.
#[derive(Debug, Clone, PartialEq)]
pub enum Loss {
    /// Each message lost independently with this probability.
    Bernoulli(f64),
    /// Gilbert–Elliott: (p_enter_bad, p_leave_bad, loss_good, loss_bad).
    Burst {
        p_enter_bad: f64,
        p_leave_bad: f64,
        loss_good: f64,
        loss_bad: f64,
    },
}

/// Everything the mission says about one directed link.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkSpec {
    pub loss: Loss,
    /// s
    pub delay: f64,
    /// [start, end) windows in which every message is lost.
    pub outages: Vec<(f64, f64)>,
    /// Acoustic models (D21): nothing beyond `range` (m); loss rising linearly with distance to
    /// `loss_at_range` at the range; propagation delay distance / `sound_speed`.
    pub range: Option<f64>,
    pub loss_at_range: f64,
    pub sound_speed: Option<f64>,
    /// The acoustic modems of D23, with this link's source and noise levels: the physics decides
    /// every frame before any of the above.
    pub modem: Option<ModemConfig>,
}

/// m/s: the speed of sound a modem's frames travel at unless `sound_speed` says otherwise (D23).
pub const SOUND_SPEED: f64 = 1500.0;

impl LinkSpec {
    /// The link j→i as `[comms]` declares it: defaults, then `[[comms.link]]` overrides.
    pub fn of(mission: &Mission, from: u32, to: u32) -> LinkSpec {
        let c = &mission.comms;
        let over = c.links.iter().find(|l| (l.from, l.to) == (from, to));
        let loss = match (&c.burst, over.and_then(|o| o.loss)) {
            (_, Some(p)) => Loss::Bernoulli(p),
            (Some(b), None) => Loss::Burst {
                p_enter_bad: b.p_enter_bad,
                p_leave_bad: b.p_leave_bad,
                loss_good: b.loss_good,
                loss_bad: b.loss_bad,
            },
            (None, None) => Loss::Bernoulli(c.loss),
        };
        LinkSpec {
            loss,
            delay: over.and_then(|o| o.delay).unwrap_or(c.delay),
            outages: c
                .outages
                .iter()
                .filter(|o| o.from.matches(from) && o.to.matches(to))
                .map(|o| (o.start, o.end))
                .collect(),
            range: over.and_then(|o| o.range).or(c.range),
            loss_at_range: over.and_then(|o| o.loss_at_range).unwrap_or(c.loss_at_range),
            sound_speed: over.and_then(|o| o.sound_speed).or(c.sound_speed),
            modem: c.modem.map(|m| ModemConfig {
                source_level: over.and_then(|o| o.source_level).unwrap_or(m.source_level),
                noise_level: over.and_then(|o| o.noise_level).unwrap_or(m.noise_level),
                ..m
            }),
        }
    }

    /// m/s: how fast a message travels, if its travel counts at all.
    pub fn sound_speed(&self) -> Option<f64> {
        self.sound_speed.or(self.modem.map(|_| SOUND_SPEED))
    }

    /// s: how long a message sent across `distance` metres travels, until its last bit is in
    /// when a modem sends it (D21, D23).
    pub fn delay(&self, distance: f64) -> f64 {
        self.delay + self.sound_speed().map_or(0.0, |c| distance / c) + self.modem.map_or(0.0, |m| m.airtime())
    }

    /// s: the longest any message on this link travels: to the range, or with a modem to R₉₉,
    /// beyond which hardly any frame survives (validation bounds the propagation delay by them).
    pub fn max_delay(&self) -> f64 {
        let reach = match self.modem {
            Some(m) => m.range_at(0.99),
            None => self.range.unwrap_or(0.0),
        };
        self.delay(reach)
    }
}

#[derive(Debug, Clone)]
pub struct Link {
    pub from: u32,
    pub to: u32,
    spec: LinkSpec,
    bad: bool,
    rng: ChaCha8Rng,
    /// The modem's error draws (D23), a stream of their own so that a modem leaves the link's
    /// other draws as they were.
    phy: Option<ChaCha8Rng>,
}

fn stream(seed: u64, from: u32, to: u32, name: &[u8; 16]) -> ChaCha8Rng {
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&seed.to_le_bytes());
    key[8..12].copy_from_slice(&from.to_le_bytes());
    key[12..16].copy_from_slice(&to.to_le_bytes());
    key[16..].copy_from_slice(name);
    ChaCha8Rng::from_seed(key)
}

fn uniform(rng: &mut ChaCha8Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
}

impl Link {
    pub fn new(seed: u64, from: u32, to: u32, spec: LinkSpec) -> Link {
        let mut link = Link {
            from,
            to,
            phy: spec.modem.map(|_| stream(seed, from, to, b"tcpf link phy\0\0\0")),
            spec,
            bad: false,
            rng: stream(seed, from, to, b"tcpf link loss\0\0"),
        };
        // A bursty link starts where its chain spends its time, bad with the stationary
        // probability p_enter/(p_enter + p_leave): started good, a slow chain's run lost far less
        // than its parameters imply (0.69 delivered where they say 0.5). Only bursty links draw.
        if let Loss::Burst {
            p_enter_bad,
            p_leave_bad,
            ..
        } = link.spec.loss
        {
            let switching = p_enter_bad + p_leave_bad;
            link.bad = switching > 0.0 && link.uniform() < p_enter_bad / switching;
        }
        link
    }

    pub fn spec(&self) -> &LinkSpec {
        &self.spec
    }

    fn uniform(&mut self) -> f64 {
        uniform(&mut self.rng)
    }

    /// The modem's uniform draw for the next frame sent on this link (D23): one per frame,
    /// whatever becomes of it.
    pub fn phy_draw(&mut self) -> f64 {
        uniform(
            self.phy
                .as_mut()
                .expect("a draw for a modem's frame on a link with a modem"),
        )
    }

    /// Advances the link to the communication instant t and says what becomes of a message sent
    /// then across `distance` (if one was sent): delivered, or the cause that lost it (an outage
    /// named first, then the range, then the link's loss). Called once per instant whether or not
    /// a message was sent, and drawing the same number of numbers every time, so that the stream
    /// stays aligned with time.
    pub fn transmit(&mut self, t: f64, distance: Option<f64>) -> Cause {
        let lost = match self.spec.loss {
            Loss::Bernoulli(p) => self.uniform() < p,
            Loss::Burst {
                p_enter_bad,
                p_leave_bad,
                loss_good,
                loss_bad,
            } => {
                let switch = self.uniform() < if self.bad { p_leave_bad } else { p_enter_bad };
                self.bad ^= switch;
                self.uniform() < if self.bad { loss_bad } else { loss_good }
            }
        };
        // Only missions with a range draw for it, so that every other run keeps its stream.
        let out_of_reach = match self.spec.range {
            Some(range) => {
                let u = self.uniform();
                distance.is_some_and(|d| d > range || u < self.spec.loss_at_range * d / range)
            }
            None => false,
        };
        if self.spec.outages.iter().any(|&(start, end)| start <= t && t < end) {
            Cause::Outage
        } else if out_of_reach {
            Cause::Range
        } else if lost {
            match self.spec.loss {
                Loss::Bernoulli(_) => Cause::Loss,
                Loss::Burst { .. } => Cause::Burst,
            }
        } else {
            Cause::Delivered
        }
    }
}

/// A link's frames by what became of them, written as `{"delivered": 559, "half_duplex": 2}`
/// (the causes that occurred).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "BTreeMap<Cause, u64>", from = "BTreeMap<Cause, u64>")]
pub struct Causes([u64; Cause::ALL.len()]);

impl Causes {
    pub fn add(&mut self, cause: Cause) {
        self.0[cause as usize] += 1;
    }

    pub fn get(&self, cause: Cause) -> u64 {
        self.0[cause as usize]
    }

    pub fn is_empty(&self) -> bool {
        self.0.iter().all(|&n| n == 0)
    }
}

impl From<Causes> for BTreeMap<Cause, u64> {
    fn from(c: Causes) -> Self {
        Cause::ALL
            .iter()
            .map(|&k| (k, c.get(k)))
            .filter(|&(_, n)| n > 0)
            .collect()
    }
}

impl From<BTreeMap<Cause, u64>> for Causes {
    fn from(m: BTreeMap<Cause, u64>) -> Self {
        let mut c = Causes::default();
        for (k, n) in m {
            c.0[k as usize] = n;
        }
        c
    }
}

/// Per directed link counts over a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct LinkStats {
    pub from: u32,
    pub to: u32,
    /// Messages sent on the link and judged at the receiver (a modem's `busy` instants are none).
    pub sent: u64,
    pub delivered: u64,
    pub dropped: u64,
    /// Every decision on the link by cause, `busy` instants included.
    #[serde(default, skip_serializing_if = "Causes::is_empty")]
    pub causes: Causes,
    /// Delivered γ that reached the agent after their instant, when a wall-clock rule had gone on
    /// without them: never used. Always 0 in-process.
    #[serde(default)]
    pub unused: u64,
    /// Realtime: γ messages the sender published. Of them `sent` reached this receiver and were
    /// judged at an instant, `overtaken` reached it and were replaced by a newer one before an
    /// instant; the rest is what the network itself lost.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub published: Option<u64>,
    /// Realtime: γ that reached this receiver and were overtaken by a newer one from the same
    /// sender before an instant used them (the receiver woke too late to use each).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub overtaken: Option<u64>,
}

impl LinkStats {
    /// The link `from` → `to` before any message.
    pub fn new(from: u32, to: u32) -> LinkStats {
        LinkStats {
            from,
            to,
            sent: 0,
            delivered: 0,
            dropped: 0,
            causes: Causes::default(),
            unused: 0,
            published: None,
            overtaken: None,
        }
    }

    /// Counts one decision of the receiver on this link.
    pub fn count(&mut self, r: &crate::msg::Reception) {
        self.causes.add(r.cause);
        if !r.cause.was_sent() {
            return;
        }
        self.sent += 1;
        if r.delivered {
            self.delivered += 1;
        } else {
            self.dropped += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bernoulli(p: f64) -> LinkSpec {
        LinkSpec {
            loss: Loss::Bernoulli(p),
            delay: 0.0,
            outages: vec![],
            range: None,
            loss_at_range: 0.0,
            sound_speed: None,
            modem: None,
        }
    }

    #[test]
    fn gilbert_elliott_loses_in_bursts_at_its_stationary_rate() {
        let spec = LinkSpec {
            loss: Loss::Burst {
                p_enter_bad: 0.05,
                p_leave_bad: 0.2,
                loss_good: 0.0,
                loss_bad: 1.0,
            },
            delay: 0.0,
            outages: vec![],
            range: None,
            loss_at_range: 0.0,
            sound_speed: None,
            modem: None,
        };
        let mut l = Link::new(5, 1, 2, spec);
        let n = 200_000;
        let lost: Vec<bool> = (0..n).map(|_| !l.transmit(0.0, None).delivered()).collect();
        let rate = lost.iter().filter(|x| **x).count() as f64 / n as f64;
        assert!(
            (rate - 0.2).abs() < 0.01,
            "stationary bad share 0.05/(0.05+0.2) = 0.2, measured {rate}"
        );
        let runs = lost.windows(2).filter(|w| w[0] && !w[1]).count() as f64;
        let mean_burst = rate * n as f64 / runs;
        assert!(
            (mean_burst - 5.0).abs() < 0.3,
            "mean burst 1/p_leave_bad = 5, measured {mean_burst}"
        );
    }

    #[test]
    fn a_slow_bursty_link_loses_its_stationary_share_from_the_first_instant() {
        // A chain that switches once in 500 instants, half the time bad: over runs of 100
        // instants, seed after seed, half the messages are lost, the first ones too.
        let spec = LinkSpec {
            loss: Loss::Burst {
                p_enter_bad: 0.002,
                p_leave_bad: 0.002,
                loss_good: 0.0,
                loss_bad: 1.0,
            },
            ..bernoulli(0.0)
        };
        let (seeds, instants) = (2000, 100);
        let (mut lost, mut first) = (0, 0);
        for seed in 0..seeds {
            let mut l = Link::new(seed, 1, 2, spec.clone());
            for k in 0..instants {
                let gone = !l.transmit(0.1 * k as f64, None).delivered();
                lost += gone as u64;
                first += (gone && k == 0) as u64;
            }
        }
        let rate = lost as f64 / (seeds * instants) as f64;
        let first = first as f64 / seeds as f64;
        assert!((rate - 0.5).abs() < 0.05, "lost {rate}");
        assert!((first - 0.5).abs() < 0.05, "first message lost in {first} of the runs");
    }

    #[test]
    fn an_outage_loses_everything_in_its_window_and_nothing_else() {
        let spec = LinkSpec {
            loss: Loss::Bernoulli(0.0),
            outages: vec![(1.0, 2.0)],
            ..bernoulli(0.0)
        };
        let mut l = Link::new(5, 1, 2, spec);
        let got: Vec<bool> = (0..30).map(|k| l.transmit(k as f64 * 0.1, None).delivered()).collect();
        assert!(got[..10].iter().all(|x| *x) && got[10..20].iter().all(|x| !*x) && got[20..].iter().all(|x| *x));
    }

    #[test]
    fn a_links_sequence_does_not_depend_on_other_links() {
        let alone: Vec<bool> = {
            let mut l = Link::new(3, 1, 2, bernoulli(0.5));
            (0..1000).map(|_| l.transmit(0.0, None).delivered()).collect()
        };
        let mut links = [
            Link::new(3, 7, 2, bernoulli(0.5)),
            Link::new(3, 1, 2, bernoulli(0.5)),
            Link::new(3, 2, 1, bernoulli(0.5)),
        ];
        let mut interleaved = Vec::new();
        for _ in 0..1000 {
            for l in links.iter_mut() {
                let d = l.transmit(0.0, None).delivered();
                if (l.from, l.to) == (1, 2) {
                    interleaved.push(d);
                }
            }
        }
        assert_eq!(alone, interleaved);
        let mut reverse = Link::new(3, 2, 1, bernoulli(0.5));
        let other: Vec<bool> = (0..1000).map(|_| reverse.transmit(0.0, None).delivered()).collect();
        assert_ne!(alone, other, "each direction has its own stream");
    }

    #[test]
    fn loss_rate_matches_probability() {
        for p in [0.0, 0.3, 0.9, 1.0] {
            let mut l = Link::new(11, 1, 2, bernoulli(p));
            let n = 100_000;
            let lost = (0..n).filter(|_| !l.transmit(0.0, None).delivered()).count() as f64 / n as f64;
            assert!((lost - p).abs() < 0.01, "p={p} measured {lost}");
        }
    }

    #[test]
    fn acoustic_loss_rises_with_distance_and_stops_at_the_range() {
        let spec = LinkSpec {
            range: Some(100.0),
            loss_at_range: 0.6,
            sound_speed: Some(1500.0),
            ..bernoulli(0.0)
        };
        for (d, p) in [(0.0, 0.0), (50.0, 0.3), (100.0, 0.6), (100.5, 1.0), (400.0, 1.0)] {
            let mut l = Link::new(7, 1, 2, spec.clone());
            let n = 50_000;
            let lost = (0..n).filter(|_| !l.transmit(0.0, Some(d)).delivered()).count() as f64 / n as f64;
            assert!((lost - p).abs() < 0.01, "at {d} m: loss {p} expected, measured {lost}");
        }
        assert_eq!(spec.delay(300.0), 0.2, "300 m at 1500 m/s");
        assert_eq!(spec.max_delay(), 100.0 / 1500.0);
        assert_eq!(LinkSpec { delay: 1.0, ..spec }.delay(150.0), 1.1);
    }

    #[test]
    fn seeds_change_the_stream() {
        let mut a = Link::new(1, 1, 2, bernoulli(0.5));
        let mut b = Link::new(2, 1, 2, bernoulli(0.5));
        let sa: Vec<bool> = (0..64).map(|_| a.transmit(0.0, None).delivered()).collect();
        let sb: Vec<bool> = (0..64).map(|_| b.transmit(0.0, None).delivered()).collect();
        assert_ne!(sa, sb);
    }
}
