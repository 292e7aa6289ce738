//! MAVLink dialect tables: for every message of the `ardupilotmega` dialect (which
//! includes `common`, `standard`, `minimal` and friends) the facts a router needs —
//! id, name, CRC_EXTRA, payload lengths, where the target address sits, and the field
//! layout in wire order so tools can decode any field.
//!
//! The table in `ardupilotmega.rs` is generated from the official MAVLink XML by
//! `tools/gen-dialect` (see its README) and committed. Further messages are loaded from
//! MAVLink XML at run time (`dialect PATH;` in the configuration, `inspect --dialect`):
//! [`load`] reads the files, [`xml`] their elements, [`layout`] computes wire order,
//! lengths and CRC_EXTRA, and [`Dialect`] looks messages up, built-in ones first.

mod ardupilotmega;
pub mod decode;
pub mod layout;
pub mod load;
pub mod table;
pub mod xml;

pub use load::{DIALECT_FILE_LIMIT, LoadError, Loader, load_files};
pub use table::{Dialect, SETUP_SIGNING_ID, UNKNOWN_ID, UNKNOWN_MESSAGE, UNKNOWN_NAME};

/// The wire type of one message field (arrays carry their length in [`Field::array_len`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FieldType {
    /// `uint8_t` (also `uint8_t_mavlink_version`).
    U8,
    /// `int8_t`.
    I8,
    /// `uint16_t`.
    U16,
    /// `int16_t`.
    I16,
    /// `uint32_t`.
    U32,
    /// `int32_t`.
    I32,
    /// `uint64_t`.
    U64,
    /// `int64_t`.
    I64,
    /// `float`.
    F32,
    /// `double`.
    F64,
    /// `char` (a `char[N]` array is a string, NUL-padded on the wire).
    Char,
}

impl FieldType {
    /// Size in bytes of one element of this type on the wire.
    pub const fn size(self) -> usize {
        match self {
            FieldType::U8 | FieldType::I8 | FieldType::Char => 1,
            FieldType::U16 | FieldType::I16 => 2,
            FieldType::U32 | FieldType::I32 | FieldType::F32 => 4,
            FieldType::U64 | FieldType::I64 | FieldType::F64 => 8,
        }
    }
}

/// One field of a message, in wire order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Field {
    /// Field name as in the XML definition (e.g. `target_system`).
    pub name: &'static str,
    /// Element type.
    pub ty: FieldType,
    /// Number of elements for an array field; 0 for a scalar.
    pub array_len: u8,
    /// Byte offset of the field within the (untruncated) payload.
    pub offset: u16,
    /// True for MAVLink 2 extension fields (not covered by CRC_EXTRA, absent in v1).
    pub extension: bool,
}

impl Field {
    /// Total size in bytes of the field on the wire.
    pub const fn size(&self) -> usize {
        let n = if self.array_len == 0 {
            1
        } else {
            self.array_len as usize
        };
        n * self.ty.size()
    }
}

/// Everything the router and the capture tools know about one message id.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MessageInfo {
    /// Message id (24 bits on the wire in v2, 8 bits in v1).
    pub id: u32,
    /// Upper-case message name (e.g. `HEARTBEAT`).
    pub name: &'static str,
    /// The CRC_EXTRA seed byte folded into the frame checksum.
    pub crc_extra: u8,
    /// Payload length without extension fields (the v1 length).
    pub min_len: u8,
    /// Payload length with all extension fields.
    pub max_len: u8,
    /// Offset of the target system byte in the payload, if the message has one
    /// (`target_system`, or `target` for MANUAL_CONTROL).
    pub target_system_offset: Option<u8>,
    /// Offset of the `target_component` byte in the payload, if the message has one.
    pub target_component_offset: Option<u8>,
    /// Fields in wire order.
    pub fields: &'static [Field],
}

/// Name of the dialect the tables were generated from.
pub const DIALECT_NAME: &str = "ardupilotmega";

/// All messages of the dialect, sorted by id.
pub fn messages() -> &'static [MessageInfo] {
    &ardupilotmega::MESSAGES
}

/// Ids below this are looked up in a flat table (the hot path: nearly all traffic).
const DENSE_IDS: usize = 512;
/// No message at this id in [`DENSE`].
const ABSENT: u16 = u16::MAX;

/// Index into the message table for every id below [`DENSE_IDS`], built at compile time.
static DENSE: [u16; DENSE_IDS] = {
    let mut table = [ABSENT; DENSE_IDS];
    let mut i = 0;
    while i < ardupilotmega::MESSAGES.len() {
        let id = ardupilotmega::MESSAGES[i].id as usize;
        if id < DENSE_IDS {
            table[id] = i as u16;
        }
        i += 1;
    }
    table
};

/// Look a message up by id; `None` for ids the dialect does not define.
#[inline]
pub fn by_id(id: u32) -> Option<&'static MessageInfo> {
    let index = match DENSE.get(id as usize) {
        Some(&ABSENT) => return None,
        Some(&i) => i as usize,
        None => ardupilotmega::index_of(id)?,
    };
    Some(&ardupilotmega::MESSAGES[index])
}

/// Look a message up by its exact (upper-case) name.
pub fn by_name(name: &str) -> Option<&'static MessageInfo> {
    ardupilotmega::BY_NAME
        .binary_search_by(|(n, _)| (*n).cmp(name))
        .ok()
        .map(|i| &ardupilotmega::MESSAGES[ardupilotmega::BY_NAME[i].1 as usize])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn by_id_agrees_with_a_linear_search_for_every_24_bit_id_that_matters() {
        // Every id up to 2^16 plus the ends of the 24-bit range.
        for id in (0..=65_536u32).chain([0xff_fffe, 0xff_ffff, u32::MAX]) {
            let linear = messages().iter().find(|m| m.id == id);
            assert_eq!(by_id(id).map(|m| m.id), linear.map(|m| m.id), "id {id}");
        }
    }

    #[test]
    fn by_name_finds_every_message_and_nothing_else() {
        for m in messages() {
            assert_eq!(by_name(m.name).map(|x| x.id), Some(m.id));
        }
        assert!(by_name("heartbeat").is_none());
        assert!(by_name("NOT_A_MSG").is_none());
    }
}
