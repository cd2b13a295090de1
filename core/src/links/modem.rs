//! The acoustic physical layer (MODEL D23): what becomes of a γ frame between two half-duplex
//! modems in the water. Thorp's absorption and spreading give the received level, the noise in
//! band and every other frame overlapping it at the receiver give its SINR, uncoded BPSK gives its
//! error rate. Pure functions of the mission's `[comms.modem]` and the distances, and a
//! `Receiver` that keeps, at one vehicle, the frames in the water until each can be judged.

use std::collections::VecDeque;

use crate::mission::{Mission, ModemConfig, Trigger};

/// dB/km: Thorp's absorption at `f` kHz (D23).
pub fn thorp(f: f64) -> f64 {
    let f2 = f * f;
    0.11 * f2 / (1.0 + f2) + 44.0 * f2 / (4100.0 + f2) + 2.75e-4 * f2 + 0.003
}

/// A dB level as power, in the units of the level's reference (µPa²).
pub fn power(db: f64) -> f64 {
    10f64.powf(db / 10.0)
}

/// A power ratio in dB.
pub fn db(ratio: f64) -> f64 {
    10.0 * ratio.log10()
}

impl ModemConfig {
    /// dB: spreading plus absorption over `distance` m, taken as 1 m below 1 m (D23).
    pub fn transmission_loss(&self, distance: f64) -> f64 {
        let d = distance.max(1.0);
        self.spreading * 10.0 * d.log10() + thorp(self.frequency) * d / 1000.0
    }

    /// dB re 1 µPa: the level of a frame received across `distance` m.
    pub fn received_level(&self, distance: f64) -> f64 {
        self.source_level - self.transmission_loss(distance)
    }

    /// dB re 1 µPa: the ambient noise in the band, N = NL + 10 log₁₀ B.
    pub fn noise(&self) -> f64 {
        self.noise_level + db(self.bandwidth * 1000.0)
    }

    /// s: how long one frame occupies the sender's modem and the water at any receiver.
    pub fn airtime(&self) -> f64 {
        self.preamble + self.frame_bits / self.bitrate
    }

    /// dB: the signal-to-noise ratio of an isolated frame across `distance` m.
    pub fn snr(&self, distance: f64) -> f64 {
        self.received_level(distance) - self.noise()
    }

    /// The probability that a frame received at `sinr` (a power ratio, not dB) has an error:
    /// uncoded BPSK, Eb/N0 = SINR·B/R, BER = ½ erfc(√(Eb/N0)), PER = 1 − (1 − BER)^bits.
    pub fn per(&self, sinr: f64) -> f64 {
        let eb_n0 = sinr * self.bandwidth * 1000.0 / self.bitrate;
        let ber = 0.5 * libm::erfc(eb_n0.max(0.0).sqrt());
        // 1 − (1 − BER)^L without cancellation at a BER of 1e-9.
        -(self.frame_bits * (-ber).ln_1p()).exp_m1()
    }

    /// The error rate of an isolated frame across `distance` m.
    pub fn per_at(&self, distance: f64) -> f64 {
        self.per(power(self.snr(distance)))
    }

    /// m: the distance at which an isolated frame's error rate reaches `p` (R₁₀ for 0.1, …). The
    /// error rate grows with distance, so a bisection finds it to a millimetre.
    pub fn range_at(&self, p: f64) -> f64 {
        let (mut lo, mut hi) = (1.0, 1.0);
        while self.per_at(hi) < p && hi < 1e9 {
            (lo, hi) = (hi, hi * 2.0);
        }
        while hi - lo > 1e-4 {
            let mid = 0.5 * (lo + hi);
            if self.per_at(mid) < p {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }
}

/// What `tcpf plan` says of a mission's modems: the airtime, the distances at which an isolated
/// frame fails one time in ten, two, … and the medium access that cannot work with them.
pub fn link_budget(mission: &Mission) -> Option<Vec<String>> {
    let m = mission.comms.modem?;
    let k = &mission.comms;
    let c = k.sound_speed.unwrap_or(crate::links::SOUND_SPEED);
    let t = m.airtime();
    let r99 = m.range_at(0.99);
    let mut lines = vec![
        format!(
            "modem: airtime {t:.4} s ({} bits at {} bit/s after a {} s preamble), SNR {:.1} dB at 1 km",
            m.frame_bits,
            m.bitrate,
            m.preamble,
            m.snr(1000.0)
        ),
        format!(
            "modem: an isolated frame fails 1 in 10 at R10 = {:.1} m, 1 in 2 at R50 = {:.1} m, 9 in 10 at R90 = {:.1} m, 99 in 100 at R99 = {r99:.1} m",
            m.range_at(0.1),
            m.range_at(0.5),
            m.range_at(0.9)
        ),
    ];
    if k.trigger == Trigger::Periodic && k.tdma_slot.is_none() && k.period < t {
        lines.push(format!(
            "warning: the periodic trigger (every {} s) is faster than the airtime ({t:.4} s): every other instant finds the modem busy, and every vehicle sends at once, each deaf to the others while it talks (half duplex)",
            k.period
        ));
    }
    if let Some(slot) = k.tdma_slot.filter(|&s| s < t + r99 / c) {
        lines.push(format!(
            "warning: TDMA slots of {slot} s are shorter than the airtime plus the propagation over R99 ({t:.4} + {:.4} = {:.4} s): a frame from afar may still arrive in the next vehicle's slot",
            r99 / c,
            t + r99 / c
        ));
    }
    Some(lines)
}

/// Why a γ frame on a link was not delivered, or that it was (D23, and D12/D21 on top).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Cause {
    Delivered,
    /// The sender's trigger fired while its modem still transmitted: nothing was sent.
    Busy,
    /// The receiver's own modem transmitted while the frame arrived.
    HalfDuplex,
    /// Lost to the error draw while another frame overlapped it.
    Collision,
    /// Lost to the error draw, alone in the water.
    Noise,
    /// The link's independent loss (`loss`).
    Loss,
    /// The link's Gilbert–Elliott loss (`[comms.burst]`).
    Burst,
    /// A `[[comms.outage]]` window.
    Outage,
    /// Beyond `range`, or lost to `loss_at_range` (D21).
    Range,
}

impl Cause {
    pub const ALL: [Cause; 9] = [
        Cause::Delivered,
        Cause::Busy,
        Cause::HalfDuplex,
        Cause::Collision,
        Cause::Noise,
        Cause::Loss,
        Cause::Burst,
        Cause::Outage,
        Cause::Range,
    ];

    pub fn delivered(self) -> bool {
        self == Cause::Delivered
    }

    /// Whether a frame went into the water: a busy modem's instant sent none, and is counted by
    /// its cause alone, never as a message sent.
    pub fn was_sent(self) -> bool {
        self != Cause::Busy
    }

    /// The word `messages.csv`, the summary and the sweep's columns use.
    pub fn name(self) -> &'static str {
        match self {
            Cause::Delivered => "delivered",
            Cause::Busy => "busy",
            Cause::HalfDuplex => "half_duplex",
            Cause::Collision => "collision",
            Cause::Noise => "noise",
            Cause::Loss => "loss",
            Cause::Burst => "burst",
            Cause::Outage => "outage",
            Cause::Range => "range",
        }
    }
}

/// A frame in the water as one receiver hears it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Arrival {
    pub from: u32,
    /// t_s, s: the sending instant.
    pub sent: f64,
    /// a, s: when its first bit reaches the receiver, t_s + d/c.
    pub start: f64,
    /// dB re 1 µPa: its received level (a level, so that no distance or level makes it 0 or ∞).
    pub level: f64,
}

/// What the physics made of one frame at one receiver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Judgement {
    /// dB, `None` when the receiver was itself transmitting.
    pub sinr_db: Option<f64>,
    /// `Delivered`, `HalfDuplex`, `Collision` or `Noise`.
    pub cause: Cause,
}

/// One vehicle's modem as a receiver: its own sending instants and the frames of every vehicle
/// that may still overlap one not yet judged.
#[derive(Debug, Clone, Default)]
pub struct Receiver {
    own: VecDeque<f64>,
    water: Vec<Arrival>,
}

impl Receiver {
    /// This modem transmitted a frame at `t`.
    pub fn transmitted(&mut self, t: f64) {
        self.own.push_back(t);
    }

    /// A frame of another vehicle reaches this one.
    pub fn hear(&mut self, arrival: Arrival) {
        self.water.push(arrival);
    }

    /// How many frames are in the water: where the next instant's begin.
    pub fn heard(&self) -> usize {
        self.water.len()
    }

    /// Puts the frames heard since `start` in the order of their senders' ids: interference is
    /// summed in this order, the same whatever order the network delivered them in.
    pub fn sort_from(&mut self, start: usize) {
        self.water[start..].sort_unstable_by_key(|a| a.from);
    }

    /// The frame `wanted` (heard before) judged with `u`, the link's uniform draw for it:
    /// half duplex if this modem transmitted during [a, a + T); else delivered iff u ≥ PER at the
    /// worst-case SINR over the frame, S / (N + ΣI) with every other overlapping frame's power.
    pub fn judge(&self, modem: &ModemConfig, wanted: &Arrival, u: f64) -> Judgement {
        let airtime = modem.airtime();
        let overlaps = |start: f64| start < wanted.start + airtime && start + airtime > wanted.start;
        if self.own.iter().any(|&t| overlaps(t)) {
            return Judgement {
                sinr_db: None,
                cause: Cause::HalfDuplex,
            };
        }
        // Summed in the order heard, each instant's frames by sender id (`sort_from`): the same
        // bits in every process whatever order the network delivered the frames in.
        let interference: f64 = self
            .water
            .iter()
            .filter(|a| !(a.from == wanted.from && a.sent == wanted.sent) && overlaps(a.start))
            .map(|a| power(a.level))
            .sum();
        let sinr_db = wanted.level - db(power(modem.noise()) + interference);
        let cause = if u >= modem.per(power(sinr_db)) {
            Cause::Delivered
        } else if interference > 0.0 {
            Cause::Collision
        } else {
            Cause::Noise
        };
        Judgement {
            sinr_db: Some(sinr_db),
            cause,
        }
    }

    /// Forgets what can overlap no frame starting at `from` or later.
    pub fn forget_before(&mut self, from: f64, airtime: f64) {
        while self.own.front().is_some_and(|&t| t + airtime <= from) {
            self.own.pop_front();
        }
        self.water.retain(|a| a.start + airtime > from);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn defaults() -> ModemConfig {
        ModemConfig::default()
    }

    fn close(a: f64, b: f64, tol: f64, what: &str) {
        assert!((a - b).abs() <= tol, "{what}: {a} against {b} (± {tol})");
    }

    #[test]
    fn the_closed_form_figures_of_d23() {
        let m = defaults();
        close(thorp(25.0), 6.104805, 1e-6, "Thorp at 25 kHz, dB/km");
        close(m.noise(), 86.9897, 1e-4, "noise in 5 kHz at NL 50, dB");
        close(m.airtime(), 0.1512, 1e-12, "airtime, s");
        for (d, snr, per) in [
            (1000.0, 31.9055, 0.0),
            (3000.0, 12.5391, 2.7e-7),
            (3500.0, 8.4825, 0.021923),
            (4000.0, 4.5602, 0.884862),
            (4500.0, 0.7405, 1.0),
        ] {
            close(m.snr(d), snr, 1e-4, &format!("SNR at {d} m"));
            close(m.per_at(d), per, 1e-6, &format!("PER at {d} m"));
        }
        let ber = 0.5 * libm::erfc(power(m.snr(3000.0)).sqrt());
        close(ber, 1.05e-9, 0.01e-9, "BER at 3 000 m");
    }

    #[test]
    fn the_ranges_at_which_isolated_frames_fail() {
        let m = defaults();
        close(m.range_at(0.1), 3626.68, 0.01, "R10");
        close(m.range_at(0.5), 3830.65, 0.01, "R50");
        close(m.range_at(0.9), 4010.95, 0.01, "R90");
        let quiet = ModemConfig {
            source_level: 120.0,
            ..defaults()
        };
        close(quiet.range_at(0.1), 48.149, 0.001, "R10 at SL 120");
        close(quiet.range_at(0.5), 60.842, 0.001, "R50 at SL 120");
        close(quiet.range_at(0.9), 74.475, 0.001, "R90 at SL 120");
        for (d, per) in [(40.0, 0.014055), (50.0, 0.138517), (60.0, 0.467342), (70.0, 0.807936)] {
            close(quiet.per_at(d), per, 1e-6, &format!("PER at {d} m, SL 120"));
        }
        assert!(m.range_at(0.99) > m.range_at(0.9));
    }

    fn arrival(from: u32, sent: f64, distance: f64, m: &ModemConfig) -> Arrival {
        Arrival {
            from,
            sent,
            start: sent + distance / 1500.0,
            level: m.received_level(distance),
        }
    }

    #[test]
    fn overlapping_frames_interfere_as_sinr() {
        let m = defaults();
        let sinr = |wanted: f64, other: f64| {
            let mut rx = Receiver::default();
            let w = arrival(1, 0.0, wanted, &m);
            rx.hear(w);
            // The other frame starts so that both arrive together.
            rx.hear(Arrival {
                from: 2,
                sent: 0.0,
                start: w.start,
                level: m.received_level(other),
            });
            rx.judge(&m, &w, 1.0 - 1e-15)
        };
        let equal = sinr(100.0, 100.0);
        close(equal.sinr_db.unwrap(), 0.0, 1e-4, "equal powers, dB");
        close(
            m.per(power(equal.sinr_db.unwrap())),
            0.9999999992,
            1e-10,
            "equal powers, PER",
        );
        let far = sinr(10.0, 200.0);
        close(far.sinr_db.unwrap(), 20.6753, 1e-4, "10 m against 200 m");
        assert_eq!(far.cause, Cause::Delivered, "captured");
        for (other, want, per) in [(30.0, 7.2789, 0.1289), (20.0, 4.5765, 0.8818)] {
            let j = sinr(10.0, other);
            close(j.sinr_db.unwrap(), want, 1e-4, &format!("10 m against {other} m"));
            close(m.per(power(want)), per, 1e-4, &format!("PER against {other} m"));
        }
        // A draw below the PER is lost, and named after the interferer.
        let mut rx = Receiver::default();
        let w = arrival(1, 0.0, 10.0, &m);
        rx.hear(w);
        rx.hear(arrival(2, 0.0, 20.0, &m));
        assert_eq!(rx.judge(&m, &w, 0.5).cause, Cause::Collision);
        assert_eq!(rx.judge(&m, &w, 0.9).cause, Cause::Delivered);
    }

    #[test]
    fn a_frame_overlaps_only_what_is_in_the_water_with_it() {
        let m = defaults();
        let t = m.airtime();
        let mut rx = Receiver::default();
        let w = arrival(1, 1.0, 15.0, &m);
        rx.hear(w);
        // Ends exactly as the wanted frame begins; begins exactly as it ends: no overlap.
        for start in [w.start - t, w.start + t] {
            rx.hear(Arrival {
                from: 3,
                sent: start,
                start,
                level: 300.0,
            });
        }
        let alone = rx.judge(&m, &w, 0.5);
        close(alone.sinr_db.unwrap(), m.snr(15.0), 1e-9, "isolated frame");
        assert_eq!(alone.cause, Cause::Delivered);
        // The receiver talks while the frame arrives: half duplex, whatever the draw.
        rx.transmitted(w.start + t - 1e-6);
        assert_eq!(rx.judge(&m, &w, 1.0).cause, Cause::HalfDuplex);
        assert_eq!(rx.judge(&m, &w, 1.0).sinr_db, None);
        // A frame far out of range is lost to noise, at an SINR that stays a number however far.
        let far = arrival(2, 0.0, 5000.0, &m);
        assert_eq!(Receiver::default().judge(&m, &far, 0.999).cause, Cause::Noise);
        let beyond = arrival(2, 0.0, 1e6, &m);
        let judged = Receiver::default().judge(&m, &beyond, 0.999);
        assert!(
            judged.sinr_db.is_some_and(|s| s.is_finite() && s < -6000.0),
            "{judged:?}"
        );
    }

    #[test]
    fn the_plan_names_the_airtime_the_ranges_and_medium_access_that_cannot_work() {
        let paper = crate::fixtures::case_b().0;
        assert_eq!(link_budget(&paper), None, "no modem, nothing to say");
        let modem = Mission {
            comms: crate::mission::CommsConfig {
                modem: Some(defaults()),
                ..paper.comms.clone()
            },
            ..paper.clone()
        };
        let lines = link_budget(&modem).unwrap().join("\n");
        for says in [
            "airtime 0.1512 s",
            "R10 = 3626.7 m",
            "R50 = 3830.7 m",
            "R90 = 4010.9 m",
            "faster than the airtime",
        ] {
            assert!(lines.contains(says), "{says}: {lines}");
        }
        let mut tdma = modem.clone();
        tdma.comms.tdma_slot = Some(0.5);
        let lines = link_budget(&tdma).unwrap().join("\n");
        assert!(
            lines.contains("TDMA slots of 0.5 s are shorter than the airtime plus the propagation over R99"),
            "{lines}"
        );
        assert!(!lines.contains("faster than the airtime"), "{lines}");
        tdma.comms.tdma_slot = Some(3.0);
        assert_eq!(link_budget(&tdma).unwrap().len(), 2, "slots long enough: no warning");
    }

    #[test]
    fn forgetting_keeps_whatever_may_still_overlap() {
        let m = defaults();
        let t = m.airtime();
        let mut rx = Receiver::default();
        rx.transmitted(0.0);
        rx.transmitted(0.2);
        rx.hear(arrival(2, 0.0, 10.0, &m));
        rx.hear(arrival(2, 0.2, 10.0, &m));
        // The frame of 0.0 arrives 6.7 ms late and ends at 0.158 s.
        rx.forget_before(0.15, t);
        assert_eq!((rx.own.len(), rx.water.len()), (2, 2));
        rx.forget_before(0.2, t);
        assert_eq!((rx.own.len(), rx.water.len()), (1, 1));
        rx.forget_before(0.4, t);
        assert_eq!((rx.own.len(), rx.water.len()), (0, 0));
    }
}
