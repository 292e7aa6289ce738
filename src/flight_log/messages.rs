//! The messages of the log streams, read from received frames and built for the
//! router's requests and acknowledgements (MAVLink 2, the ardupilotmega and common
//! dialects; byte offsets are the wire order, largest fields first).

use crate::address::Address;
use crate::wire::Frame;
use crate::wire::encode::{Header, encode_v2};

/// HEARTBEAT.
pub(crate) const HEARTBEAT: u32 = 0;
/// COMMAND_LONG.
pub(crate) const COMMAND_LONG: u32 = 76;
/// COMMAND_ACK.
pub(crate) const COMMAND_ACK: u32 = 77;
/// REMOTE_LOG_DATA_BLOCK: seqno u32, target_system, target_component, data[200].
pub(crate) const REMOTE_LOG_DATA_BLOCK: u32 = 184;
/// REMOTE_LOG_BLOCK_STATUS: seqno u32, target_system, target_component, status.
pub(crate) const REMOTE_LOG_BLOCK_STATUS: u32 = 185;
/// LOGGING_DATA: sequence u16, target_system, target_component, length,
/// first_message_offset, data[249].
pub(crate) const LOGGING_DATA: u32 = 266;
/// LOGGING_DATA_ACKED: as LOGGING_DATA, answered with LOGGING_ACK.
pub(crate) const LOGGING_DATA_ACKED: u32 = 267;
/// LOGGING_ACK: sequence u16, target_system, target_component.
pub(crate) const LOGGING_ACK: u32 = 268;

/// MAV_REMOTE_LOG_DATA_BLOCK_START: the seqno asking ArduPilot to start streaming.
pub(crate) const DATA_BLOCK_START: u32 = 2_147_483_646;
/// MAV_REMOTE_LOG_DATA_BLOCK_STOP: the seqno asking ArduPilot to stop.
pub(crate) const DATA_BLOCK_STOP: u32 = 2_147_483_645;
/// MAV_REMOTE_LOG_DATA_BLOCK_NACK.
pub(crate) const BLOCK_NACK: u8 = 0;
/// MAV_REMOTE_LOG_DATA_BLOCK_ACK.
pub(crate) const BLOCK_ACK: u8 = 1;
/// Bytes of log in one REMOTE_LOG_DATA_BLOCK.
pub(crate) const DATAFLASH_BLOCK: usize = 200;

/// MAV_CMD_LOGGING_START (param1 0: ULog).
pub(crate) const CMD_LOGGING_START: u16 = 2510;
/// MAV_CMD_LOGGING_STOP.
pub(crate) const CMD_LOGGING_STOP: u16 = 2511;

/// MAV_AUTOPILOT_ARDUPILOTMEGA.
pub(crate) const AUTOPILOT_ARDUPILOT: u8 = 3;
/// MAV_AUTOPILOT_INVALID: the heartbeat is not an autopilot's.
pub(crate) const AUTOPILOT_INVALID: u8 = 8;
/// MAV_AUTOPILOT_PX4.
pub(crate) const AUTOPILOT_PX4: u8 = 12;
/// MAV_MODE_FLAG_SAFETY_ARMED in HEARTBEAT.base_mode.
pub(crate) const SAFETY_ARMED: u8 = 128;

/// What an autopilot's HEARTBEAT says: its kind (MAV_AUTOPILOT) and whether it is armed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Beat {
    pub autopilot: u8,
    pub armed: bool,
}

/// The HEARTBEAT in `frame`, if it is an autopilot's.
pub(crate) fn heartbeat(frame: &Frame<'_>) -> Option<Beat> {
    let p = frame.payload_padded();
    // custom_mode u32, type, autopilot, base_mode, system_status, mavlink_version.
    let autopilot = p[5];
    (autopilot != AUTOPILOT_INVALID).then_some(Beat {
        autopilot,
        armed: p[6] & SAFETY_ARMED != 0,
    })
}

/// A REMOTE_LOG_DATA_BLOCK's seqno and data.
pub(crate) fn dataflash_block(frame: &Frame<'_>) -> (u32, [u8; DATAFLASH_BLOCK]) {
    let p = frame.payload_padded();
    let seqno = u32::from_le_bytes([p[0], p[1], p[2], p[3]]);
    let mut data = [0u8; DATAFLASH_BLOCK];
    data.copy_from_slice(&p[6..6 + DATAFLASH_BLOCK]);
    (seqno, data)
}

/// A LOGGING_DATA(_ACKED): sequence, first_message_offset and the data (`length`
/// bytes, at most 249).
pub(crate) struct UlogChunk {
    pub sequence: u16,
    pub first_message_offset: u8,
    pub data: Vec<u8>,
}

/// The LOGGING_DATA or LOGGING_DATA_ACKED in `frame`.
pub(crate) fn ulog_chunk(frame: &Frame<'_>) -> UlogChunk {
    let p = frame.payload_padded();
    let len = usize::from(p[4]).min(249);
    UlogChunk {
        sequence: u16::from_le_bytes([p[0], p[1]]),
        first_message_offset: p[5],
        data: p[6..6 + len].to_vec(),
    }
}

/// The command a COMMAND_ACK answers.
pub(crate) fn acked_command(frame: &Frame<'_>) -> u16 {
    let p = frame.payload_padded();
    u16::from_le_bytes([p[0], p[1]])
}

/// A frame of message `id` with `payload` from `from` with sequence `seq`.
fn build(from: Address, seq: u8, id: u32, payload: &[u8]) -> Vec<u8> {
    let header = Header {
        seq,
        system: from.system,
        component: from.component,
    };
    let mut out = Vec::with_capacity(payload.len() + 12);
    // Each id is in the built-in dialect and each payload within its length.
    let _ = encode_v2(header, id, payload, None, &mut out);
    out
}

/// REMOTE_LOG_BLOCK_STATUS from `from` to `to` for `seqno` with `status`.
pub(crate) fn block_status(from: Address, seq: u8, to: Address, seqno: u32, status: u8) -> Vec<u8> {
    let s = seqno.to_le_bytes();
    let payload = [s[0], s[1], s[2], s[3], to.system, to.component, status];
    build(from, seq, REMOTE_LOG_BLOCK_STATUS, &payload)
}

/// COMMAND_LONG `command` with param1 0, from `from` to `to`.
pub(crate) fn command(from: Address, seq: u8, to: Address, command: u16) -> Vec<u8> {
    let mut payload = [0u8; 33];
    payload[28..30].copy_from_slice(&command.to_le_bytes());
    payload[30] = to.system;
    payload[31] = to.component;
    build(from, seq, COMMAND_LONG, &payload)
}

/// LOGGING_ACK of `sequence` from `from` to `to`.
pub(crate) fn logging_ack(from: Address, seq: u8, to: Address, sequence: u16) -> Vec<u8> {
    let s = sequence.to_le_bytes();
    build(
        from,
        seq,
        LOGGING_ACK,
        &[s[0], s[1], to.system, to.component],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_block_status_parses_back() {
        let bytes = block_status(Address::new(245, 190), 3, Address::new(1, 1), 77, BLOCK_ACK);
        let frame = Frame::parse_exact(&bytes).expect("valid frame");
        assert_eq!(frame.message_id(), REMOTE_LOG_BLOCK_STATUS);
        assert_eq!(frame.source(), Address::new(245, 190));
        assert_eq!(frame.target(), Some(Address::new(1, 1)));
        assert_eq!(&frame.payload_padded()[..7], &[77, 0, 0, 0, 1, 1, 1]);
    }

    #[test]
    fn a_command_targets_the_autopilot() {
        let bytes = command(
            Address::new(245, 190),
            0,
            Address::new(1, 1),
            CMD_LOGGING_START,
        );
        let frame = Frame::parse_exact(&bytes).expect("valid frame");
        assert_eq!(frame.target(), Some(Address::new(1, 1)));
        let p = frame.payload_padded();
        assert_eq!(u16::from_le_bytes([p[28], p[29]]), 2510);
    }
}
