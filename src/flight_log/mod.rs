//! Flight logs streamed from the autopilot to the router (the `flight_log` block),
//! sans-IO; the file writer is `src/io/flight_log.rs`.
//!
//! The protocols, as the autopilots speak them:
//! - ArduPilot (HEARTBEAT.autopilot 3, MAV_AUTOPILOT_ARDUPILOTMEGA): the router sends
//!   REMOTE_LOG_BLOCK_STATUS (185) with seqno MAV_REMOTE_LOG_DATA_BLOCK_START
//!   (2147483646) to start and ..._STOP (2147483645) to stop; the autopilot sends its
//!   dataflash log in REMOTE_LOG_DATA_BLOCK (184) of 200 bytes, numbered from 0 for each
//!   log; each block is acknowledged with status 1 (ACK) and a missing one asked for
//!   with status 0 (NACK), after which it is sent again. Written as `.bin`.
//! - PX4 (HEARTBEAT.autopilot 12): COMMAND_LONG MAV_CMD_LOGGING_START (2510) /
//!   MAV_CMD_LOGGING_STOP (2511); the ulog comes in LOGGING_DATA (266) and, for the
//!   header and definitions, LOGGING_DATA_ACKED (267), answered with LOGGING_ACK (268).
//!   A chunk carries `length` bytes and `first_message_offset`, where its first ulog
//!   message starts (255: none). Written as `.ulg`.
//!
//! Armed is HEARTBEAT.base_mode & MAV_MODE_FLAG_SAFETY_ARMED (128).
//!
//! - `messages`: reading and building those messages;
//! - `dataflash`: the order of the blocks, ACKs and NACKs;
//! - `ulog`: the order of the chunks, whole messages only;
//! - `session`: the [`FlightLogger`] state machine the engine drives;
//! - `counters`: what it counts.

pub(crate) mod counters;
pub(crate) mod dataflash;
pub(crate) mod messages;
pub(crate) mod session;
pub(crate) mod ulog;

pub use counters::{FlightLogCounters, FlightLogStats};
pub use session::{AUTOPILOT_LOST, FlightLogger, LogWrite, Protocol, START_AGAIN};
