//! Link models (SPEC D12): each directed link j→i decides, at the receiver, whether the message of
//! each communication instant is lost, from a random stream of its own. The stream is keyed by
//! (mission seed, from, to) alone, so no other link and no ordering of events can change it.

use rand_chacha::rand_core::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone)]
pub struct Link {
    pub from: u32,
    pub to: u32,
    loss: f64,
    rng: ChaCha8Rng,
}

impl Link {
    pub fn new(seed: u64, from: u32, to: u32, loss: f64) -> Link {
        let mut key = [0u8; 32];
        key[..8].copy_from_slice(&seed.to_le_bytes());
        key[8..12].copy_from_slice(&from.to_le_bytes());
        key[12..16].copy_from_slice(&to.to_le_bytes());
        key[16..].copy_from_slice(b"tcpf link loss\0\0");
        Link {
            from,
            to,
            loss,
            rng: ChaCha8Rng::from_seed(key),
        }
    }

    /// Advances the link by one communication instant and says whether a message sent in it gets
    /// through. Called once per instant whether or not a message arrived, so that the stream
    /// stays aligned with time.
    pub fn transmit(&mut self) -> bool {
        let u = (self.rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        u >= self.loss
    }
}

/// Per directed link counts over a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct LinkStats {
    pub from: u32,
    pub to: u32,
    pub sent: u64,
    pub delivered: u64,
    pub dropped: u64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_links_sequence_does_not_depend_on_other_links() {
        let alone: Vec<bool> = {
            let mut l = Link::new(3, 1, 2, 0.5);
            (0..1000).map(|_| l.transmit()).collect()
        };
        let mut links = [
            Link::new(3, 7, 2, 0.5),
            Link::new(3, 1, 2, 0.5),
            Link::new(3, 2, 1, 0.5),
        ];
        let mut interleaved = Vec::new();
        for _ in 0..1000 {
            for l in links.iter_mut() {
                let d = l.transmit();
                if (l.from, l.to) == (1, 2) {
                    interleaved.push(d);
                }
            }
        }
        assert_eq!(alone, interleaved);
        let mut reverse = Link::new(3, 2, 1, 0.5);
        let other: Vec<bool> = (0..1000).map(|_| reverse.transmit()).collect();
        assert_ne!(alone, other, "each direction has its own stream");
    }

    #[test]
    fn loss_rate_matches_probability() {
        for p in [0.0, 0.3, 0.9, 1.0] {
            let mut l = Link::new(11, 1, 2, p);
            let n = 100_000;
            let lost = (0..n).filter(|_| !l.transmit()).count() as f64 / n as f64;
            assert!((lost - p).abs() < 0.01, "p={p} measured {lost}");
        }
    }

    #[test]
    fn seeds_change_the_stream() {
        let mut a = Link::new(1, 1, 2, 0.5);
        let mut b = Link::new(2, 1, 2, 0.5);
        let sa: Vec<bool> = (0..64).map(|_| a.transmit()).collect();
        let sb: Vec<bool> = (0..64).map(|_| b.transmit()).collect();
        assert_ne!(sa, sb);
    }
}
