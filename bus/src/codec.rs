//! Payloads are postcard-encoded serde structs (docs/PROTOCOL.md). A payload is used only if it
//! decodes exactly (no trailing bytes), has our protocol version and finite numbers.

use serde::de::DeserializeOwned;
use serde::Serialize;
use tcpf_core::msg::{Checked, Unusable};

pub fn encode<T: Serialize>(message: &T) -> Vec<u8> {
    postcard::to_stdvec(message).expect("tcpf messages always encode")
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Invalid {
    Undecodable,
    Version,
    NonFinite,
}

pub fn decode<T: DeserializeOwned + Checked>(bytes: &[u8]) -> Result<T, Invalid> {
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
            0x0b, 0xac, 0x02, 0x02, 0x01,
            0, 0, 0, 0, 0, 0, 0x08, 0x40,
            0, 0, 0, 0, 0, 0, 0xf8, 0x3f,
            0, 0, 0, 0, 0, 0, 0xf0, 0x3f,
            0, 0, 0, 0, 0, 0, 0x00, 0x40,
            0, 0, 0, 0, 0, 0, 0xe0, 0xbf,
            0x00,
        ];
        assert_eq!(encode(&g), bytes);
        let silent = Gamma { sample: None, ..g };
        assert_eq!(encode(&silent), [0x0b, 0xac, 0x02, 0x02, 0x00, 0x00]);
        let busy = Gamma { busy: true, ..silent };
        assert_eq!(encode(&busy), [0x0b, 0xac, 0x02, 0x02, 0x00, 0x01]);
        let loss = Loss {
            version: PROTOCOL_VERSION,
            id: 2,
            tick: 300,
            reason: LossReason::Silent,
        };
        assert_eq!(encode(&loss), [0x0b, 0x02, 0xac, 0x02, 0x01]);
        let clock = Clock {
            version: PROTOCOL_VERSION,
            realtime: true,
            time_scale: 10.0,
            epoch: 1.5,
            tick: 300,
            mission: 5,
        };
        #[rustfmt::skip]
        let bytes = [
            0x0b, 0x01,
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
