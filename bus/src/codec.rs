//! Payloads are postcard-encoded serde structs (docs/PROTOCOL.md). A payload is used only if it
//! is no longer than its kind allows, decodes exactly (no trailing bytes), has our protocol
//! version and finite numbers.

use serde::de::DeserializeOwned;
use serde::Serialize;
use tcpf_core::msg::{Checked, Unusable};

pub fn encode<T: Serialize>(message: &T) -> Vec<u8> {
    postcard::to_stdvec(message).expect("tcpf messages always encode")
}

pub use tcpf_core::msg::Invalid;

pub fn decode<T: DeserializeOwned + Checked>(bytes: &[u8]) -> Result<T, Invalid> {
    if bytes.len() > T::MAX_BYTES {
        return Err(Invalid::TooLarge);
    }
    let (message, rest) = postcard::take_from_bytes::<T>(bytes).map_err(|_| Invalid::Undecodable)?;
    if !rest.is_empty() {
        return Err(Invalid::Undecodable);
    }
    match message.usable() {
        Ok(()) => Ok(message),
        Err(Unusable::Version) => Err(Invalid::Version),
        Err(Unusable::NonFinite) => Err(Invalid::NonFinite),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tcpf_core::msg::{
        Cause, Clock, Gamma, Loss, LossReason, Reception, Sample, State, TickRecord, PROTOCOL_VERSION,
    };
    use tcpf_core::time::UnixTime;

    fn state() -> State {
        State {
            version: PROTOCOL_VERSION,
            tick: 42,
            id: 2,
            t: 0.42,
            position: [1.0, -2.5],
            heading: 0.1,
            sideslip: 0.0,
            sideslip_rate: 0.0,
            current: [-0.1, 0.0],
            dynamics: None,
        }
    }

    #[test]
    fn encoding_matches_the_protocol_document() {
        let g = Gamma {
            version: PROTOCOL_VERSION,
            tick: 300,
            from: 2,
            sample: Some(Sample {
                t: 3.0,
                gamma: 1.5,
                gamma_dot: 1.0,
                position: [2.0, -0.5],
            }),
            busy: false,
        };
        #[rustfmt::skip]
        let bytes = [
            0x0c, 0xac, 0x02, 0x02, 0x01,
            0, 0, 0, 0, 0, 0, 0x08, 0x40,
            0, 0, 0, 0, 0, 0, 0xf8, 0x3f,
            0, 0, 0, 0, 0, 0, 0xf0, 0x3f,
            0, 0, 0, 0, 0, 0, 0x00, 0x40,
            0, 0, 0, 0, 0, 0, 0xe0, 0xbf,
            0x00,
        ];
        assert_eq!(encode(&g), bytes);
        let silent = Gamma { sample: None, ..g };
        assert_eq!(encode(&silent), [0x0c, 0xac, 0x02, 0x02, 0x00, 0x00]);
        let busy = Gamma { busy: true, ..silent };
        assert_eq!(encode(&busy), [0x0c, 0xac, 0x02, 0x02, 0x00, 0x01]);
        let loss = Loss {
            version: PROTOCOL_VERSION,
            id: 2,
            tick: 300,
            reason: LossReason::Silent,
        };
        assert_eq!(encode(&loss), [0x0c, 0x02, 0xac, 0x02, 0x01]);
        let clock = Clock {
            version: PROTOCOL_VERSION,
            realtime: true,
            time_scale: 10.0,
            epoch: UnixTime(1.5),
            tick: 300,
            mission: 5,
        };
        #[rustfmt::skip]
        let bytes = [
            0x0c, 0x01,
            0, 0, 0, 0, 0, 0, 0x24, 0x40,
            0, 0, 0, 0, 0, 0, 0xf8, 0x3f,
            0xac, 0x02, 0x05,
        ];
        assert_eq!(encode(&clock), bytes);
        let receptions = vec![
            Reception {
                from: 1,
                delivered: false,
                sent: 3.0,
                distance: Some(1500.0),
                sinr_db: Some(-2.5),
                cause: Cause::Collision,
            },
            Reception::of(3, Cause::Busy, 3.0, None),
        ];
        #[rustfmt::skip]
        let bytes = [
            0x02,
            0x01, 0x00,
            0, 0, 0, 0, 0, 0, 0x08, 0x40,
            0x01, 0, 0, 0, 0, 0, 0x70, 0x97, 0x40,
            0x01, 0, 0, 0, 0, 0, 0, 0x04, 0xc0,
            0x03,
            0x03, 0x00,
            0, 0, 0, 0, 0, 0, 0x08, 0x40,
            0x00,
            0x00,
            0x01,
        ];
        assert_eq!(encode(&receptions), bytes, "a command's receptions, as its last field");
    }

    #[test]
    fn round_trip_is_bit_exact() {
        let s = state();
        assert_eq!(decode::<State>(&encode(&s)), Ok(s));
    }

    #[test]
    fn a_tick_record_is_its_parts_in_a_row_and_each_part_must_be_usable() {
        let states = [state(), State { id: 3, ..state() }];
        let record = TickRecord {
            version: PROTOCOL_VERSION,
            tick: 42,
            states: states[..].into(),
            commands: vec![None, None].into(),
        };
        let bytes = encode(&record);
        let mut parts = vec![PROTOCOL_VERSION as u8, 42, 2];
        states.iter().for_each(|s| parts.extend(encode(s)));
        parts.extend([2, 0, 0]);
        assert_eq!(
            bytes, parts,
            "version, tick, the states as a Vec, the commands as a Vec of Options"
        );
        assert_eq!(decode::<TickRecord>(&bytes), Ok(record.clone()));
        let old = [state(), State { version: 5, ..state() }];
        let mixed = TickRecord {
            states: old[..].into(),
            ..record.clone()
        };
        assert_eq!(
            decode::<TickRecord>(&encode(&mixed)),
            Err(Invalid::Version),
            "a part of another version"
        );
        let nan = [state(), State { t: f64::NAN, ..state() }];
        let nan = TickRecord {
            states: nan[..].into(),
            ..record
        };
        assert_eq!(decode::<TickRecord>(&encode(&nan)), Err(Invalid::NonFinite));
    }

    /// The largest message of each kind that the largest mission tcpf accepts can make: every
    /// varint at its longest, every option present, every list as long as the mission allows.
    #[test]
    fn the_largest_messages_a_mission_makes_fit_their_kinds_limits_and_longer_are_refused_unread() {
        use tcpf_core::mission::{MAX_LINKS, MAX_VEHICLES};
        use tcpf_core::msg::{
            Arrival, Checked, Command, Dynamics, End, Fetch, Lost, PeriodTiming, Player, Rejections, Report,
        };
        let state = State {
            tick: u64::MAX,
            id: u32::MAX,
            dynamics: Some(Dynamics {
                surge: 1.0,
                sway: 0.0,
                yaw_rate: 0.0,
                command: [0.0; 2],
                motor: [0.0; 2],
                thrust: [0.0; 2],
            }),
            ..state()
        };
        let reception = Reception {
            from: u32::MAX,
            delivered: false,
            sent: 1.0,
            distance: Some(1.0),
            sinr_db: Some(1.0),
            cause: Cause::Collision,
        };
        let command = |receptions: usize| Command {
            version: PROTOCOL_VERSION,
            tick: u64::MAX,
            id: u32::MAX,
            v: 1.0,
            r: 0.0,
            accel: 0.0,
            hold: false,
            gamma: 1.0,
            gamma_dot: 1.0,
            v_d: 1.0,
            x_e: 0.0,
            y_e: 0.0,
            psi_e: 0.0,
            receptions: vec![reception; receptions],
        };
        let gamma = Gamma {
            version: PROTOCOL_VERSION,
            tick: u64::MAX,
            from: u32::MAX,
            sample: Some(Sample {
                t: 1.0,
                gamma: 1.0,
                gamma_dot: 1.0,
                position: [0.0; 2],
            }),
            busy: true,
        };
        // A command a tick for each of 1000 vehicles, 11 receptions a tick on each link.
        let per_vehicle = 11 * MAX_LINKS / MAX_VEHICLES;
        let states = vec![state; MAX_VEHICLES];
        let commands = vec![Some(command(per_vehicle)); MAX_VEHICLES];
        let record = TickRecord {
            version: PROTOCOL_VERSION,
            tick: u64::MAX,
            states: states.into(),
            commands: commands.into(),
        };
        let ids = 0..MAX_VEHICLES as u32;
        let end = End {
            version: PROTOCOL_VERSION,
            ticks: u64::MAX,
            lost: ids
                .clone()
                .map(|id| Lost {
                    id: u32::MAX - id,
                    tick: u64::MAX,
                    reason: LossReason::Silent,
                })
                .collect(),
            arrived: ids
                .clone()
                .map(|id| Arrival {
                    id: u32::MAX - id,
                    tick: u64::MAX,
                })
                .collect(),
        };
        let each: Vec<(u32, u64)> = ids.clone().map(|id| (u32::MAX - id, u64::MAX)).collect();
        let report = Report {
            late_gammas: each.clone(),
            timing: Some(PeriodTiming {
                periods: u64::MAX,
                without_command: each.clone(),
                rejoins: each.clone(),
                overtaken: each.clone(),
                ..PeriodTiming::default()
            }),
            rejected: Rejections {
                undecodable: u64::MAX,
                ..Rejections::default()
            },
            played: ids.map(|id| (u32::MAX - id, Player::Ros2)).collect(),
            wrong_frames: vec![(u32::MAX, "f".repeat(64), u64::MAX); 17],
            surplus_odometries: each,
            ..Report::new(tcpf_core::msg::Role::Record, u32::MAX, u32::MAX)
        };
        let clock = Clock {
            version: PROTOCOL_VERSION,
            realtime: true,
            time_scale: 1.0,
            epoch: UnixTime(1.0),
            tick: u64::MAX,
            mission: u64::MAX,
        };
        let loss = Loss {
            version: PROTOCOL_VERSION,
            id: u32::MAX,
            tick: u64::MAX,
            reason: LossReason::Silent,
        };
        /// Within its limit, and the limit not many times what a mission can make of it.
        fn fits<T: Serialize + DeserializeOwned + Checked + PartialEq + std::fmt::Debug>(m: &T, what: &str) {
            let bytes = encode(m);
            let (len, max) = (bytes.len(), T::MAX_BYTES);
            assert!(
                len <= max && 4 * len > max,
                "{what}: {len} bytes against a limit of {max}"
            );
            assert_eq!(decode::<T>(&bytes).as_ref(), Ok(m), "{what}: the largest is taken");
            let mut longer = bytes;
            longer.resize(max + 1, 0);
            assert_eq!(decode::<T>(&longer), Err(Invalid::TooLarge), "{what}");
        }
        fits(&state, "state");
        fits(&command(7 * (MAX_VEHICLES - 1)), "command");
        fits(&gamma, "γ");
        fits(&record, "tick record");
        fits(&end, "end");
        fits(&report, "report");
        fits(&clock, "clock");
        fits(&loss, "loss");
        let fetch = Fetch {
            version: PROTOCOL_VERSION,
            from: u64::MAX,
            to: u64::MAX,
            ids: (0..MAX_VEHICLES as u32).map(|id| u32::MAX - id).collect(),
        };
        fits(&fetch, "fetch");
    }

    #[test]
    fn garbage_wrong_version_and_nan_are_refused() {
        assert_eq!(decode::<State>(b"\xff\xff\xff garbage"), Err(Invalid::Undecodable));
        assert_eq!(decode::<Gamma>(&[]), Err(Invalid::Undecodable));
        let mut bytes = encode(&state());
        bytes.push(0);
        assert_eq!(decode::<State>(&bytes), Err(Invalid::Undecodable), "trailing bytes");
        let old = State {
            version: PROTOCOL_VERSION + 1,
            ..state()
        };
        assert_eq!(decode::<State>(&encode(&old)), Err(Invalid::Version));
        let nan = State {
            position: [f64::NAN, 0.0],
            ..state()
        };
        assert_eq!(decode::<State>(&encode(&nan)), Err(Invalid::NonFinite));
        let g = Gamma {
            version: PROTOCOL_VERSION,
            tick: 0,
            from: 1,
            sample: Some(Sample {
                t: 0.0,
                gamma: f64::INFINITY,
                gamma_dot: 1.0,
                position: [0.0, 0.0],
            }),
            busy: false,
        };
        assert_eq!(decode::<Gamma>(&encode(&g)), Err(Invalid::NonFinite));
    }
}
