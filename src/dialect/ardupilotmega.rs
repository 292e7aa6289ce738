// PLACEHOLDER until tools/gen-dialect writes the real table. Do not edit by hand.
use super::{Field, FieldType, MessageInfo};

static F_HEARTBEAT: [Field; 6] = [
    Field {
        name: "custom_mode",
        ty: FieldType::U32,
        array_len: 0,
        offset: 0,
        extension: false,
    },
    Field {
        name: "type",
        ty: FieldType::U8,
        array_len: 0,
        offset: 4,
        extension: false,
    },
    Field {
        name: "autopilot",
        ty: FieldType::U8,
        array_len: 0,
        offset: 5,
        extension: false,
    },
    Field {
        name: "base_mode",
        ty: FieldType::U8,
        array_len: 0,
        offset: 6,
        extension: false,
    },
    Field {
        name: "system_status",
        ty: FieldType::U8,
        array_len: 0,
        offset: 7,
        extension: false,
    },
    Field {
        name: "mavlink_version",
        ty: FieldType::U8,
        array_len: 0,
        offset: 8,
        extension: false,
    },
];

pub(super) static MESSAGES: [MessageInfo; 1] = [MessageInfo {
    id: 0,
    name: "HEARTBEAT",
    crc_extra: 50,
    min_len: 9,
    max_len: 9,
    target_system_offset: None,
    target_component_offset: None,
    fields: &F_HEARTBEAT,
}];

pub(super) static BY_NAME: [(&str, u16); 1] = [("HEARTBEAT", 0)];

pub(super) fn index_of(id: u32) -> Option<usize> {
    match id {
        0 => Some(0),
        _ => None,
    }
}
