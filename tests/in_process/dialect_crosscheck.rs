//! Cross-checks our generated `ardupilotmega` table against the independent `mavlink`
//! crate (static dialect, with MAVLink 2 extensions): ids, names, CRC_EXTRA, payload
//! lengths and target offsets, plus the internal consistency of every field list.

use std::collections::{BTreeMap, BTreeSet};
use std::panic::{self, AssertUnwindSafe};
use std::sync::Once;

use mavlink::dialects::ardupilotmega::MavMessage;
use mavlink::{MavlinkVersion, Message};
use mavtables::dialect::{MessageInfo, by_id, by_name, messages};

/// Large enough for every payload (MAVLink payloads are at most 255 bytes).
const BUF: usize = 255;

/// Byte written into a target field to find it in the serialised payload.
const SENTINEL: u8 = 0xA5;

fn reference(id: u32) -> MavMessage {
    MavMessage::default_message_from_id(id)
        .unwrap_or_else(|| panic!("mavlink crate has no message {id}"))
}

/// Serialises `msg` into a zeroed buffer and returns the whole buffer (every field is
/// written even when the returned length is truncated).
fn serialise(msg: &MavMessage, version: MavlinkVersion) -> ([u8; BUF], usize) {
    let mut buf = [0u8; BUF];
    let n = msg.ser(version, &mut buf);
    (buf, n)
}

/// Offset of the target byte reached through `get`, found by writing a sentinel
/// into it and diffing the serialised payloads.
fn sentinel_offset(id: u32, get: fn(&mut MavMessage) -> Option<&mut u8>) -> Option<u8> {
    let plain = reference(id);
    let mut marked = reference(id);
    let slot = get(&mut marked)?;
    assert_ne!(
        *slot, SENTINEL,
        "message {id}: default value equals the sentinel"
    );
    *slot = SENTINEL;
    let (a, _) = serialise(&plain, MavlinkVersion::V2);
    let (b, _) = serialise(&marked, MavlinkVersion::V2);
    let diff: Vec<usize> = (0..BUF).filter(|&i| a[i] != b[i]).collect();
    assert_eq!(diff.len(), 1, "message {id}: sentinel changed {diff:?}");
    assert_eq!(b[diff[0]], SENTINEL);
    Some(u8::try_from(diff[0]).expect("offset fits in u8"))
}

/// The crate's `ser` panics ("buffer is too small") when the buffer is shorter than
/// the message's full encoded length; silence exactly those panics while probing.
fn quiet_buffer_panics() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let previous = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            let payload = info.payload();
            let text = payload
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| payload.downcast_ref::<&str>().copied());
            let probe = text.is_some_and(|m| m.starts_with("buffer is too small"));
            if !probe {
                previous(info);
            }
        }));
    });
}

/// Whether `msg` serialises into a buffer of exactly `len` bytes without panicking.
fn fits_in(msg: &MavMessage, len: usize) -> bool {
    panic::catch_unwind(AssertUnwindSafe(|| {
        let mut buf = vec![0u8; len];
        msg.ser(MavlinkVersion::V2, &mut buf);
    }))
    .is_ok()
}

fn ours(id: u32) -> &'static MessageInfo {
    by_id(id).unwrap_or_else(|| panic!("our table has no message {id}"))
}

#[test]
fn same_ids_and_names_as_mavlink_crate() {
    let theirs: BTreeMap<u32, &str> = MavMessage::all_messages()
        .iter()
        .map(|&(name, id)| (id, name))
        .collect();
    assert_eq!(
        theirs.len(),
        MavMessage::all_messages().len(),
        "duplicate ids"
    );
    let mine: BTreeMap<u32, &str> = messages().iter().map(|m| (m.id, m.name)).collect();
    assert_eq!(mine.len(), messages().len(), "duplicate ids in our table");
    assert_eq!(mine, theirs);
    for &(name, id) in MavMessage::all_messages() {
        assert_eq!(ours(id).name, name);
        assert_eq!(by_name(name).map(|m| m.id), Some(id), "by_name({name})");
    }
}

#[test]
fn crc_extra_matches_mavlink_crate() {
    for m in messages() {
        assert_eq!(m.crc_extra, MavMessage::extra_crc(m.id), "{}", m.name);
    }
}

#[test]
fn min_len_matches_mavlink_v1_serialisation() {
    for m in messages() {
        let (_, n) = serialise(&reference(m.id), MavlinkVersion::V1);
        assert_eq!(usize::from(m.min_len), n, "{}", m.name);
    }
}

#[test]
fn max_len_matches_mavlink_encoded_len() {
    quiet_buffer_panics();
    for m in messages() {
        let msg = reference(m.id);
        let max = usize::from(m.max_len);
        assert!(
            fits_in(&msg, max),
            "{}: needs more than {max} bytes",
            m.name
        );
        assert!(
            !fits_in(&msg, max - 1),
            "{}: fits in {} bytes",
            m.name,
            max - 1
        );
    }
}

#[test]
fn target_offsets_match_mavlink_sentinels() {
    for m in messages() {
        let ts = sentinel_offset(m.id, |msg| msg.target_system_id_mut());
        let tc = sentinel_offset(m.id, |msg| msg.target_component_id_mut());
        assert_eq!(m.target_system_offset, ts, "{} target_system", m.name);
        assert_eq!(m.target_component_offset, tc, "{} target_component", m.name);
    }
}

#[test]
fn known_messages() {
    // (name, id, crc_extra, min_len, max_len, target_system, target_component)
    type Known = (&'static str, u32, u8, u8, u8, Option<u8>, Option<u8>);
    let known: [Known; 7] = [
        ("HEARTBEAT", 0, 50, 9, 9, None, None),
        ("SYS_STATUS", 1, 124, 31, 43, None, None),
        ("COMMAND_LONG", 76, 152, 33, 33, Some(30), Some(31)),
        ("MISSION_ITEM", 39, 254, 37, 38, Some(32), Some(33)),
        ("ENCAPSULATED_DATA", 131, 223, 255, 255, None, None),
        ("TIMESYNC", 111, 34, 16, 18, Some(16), Some(17)),
        ("COMMAND_ACK", 77, 143, 3, 10, Some(8), Some(9)),
    ];
    for (name, id, crc, min, max, ts, tc) in known {
        let m = by_name(name).unwrap_or_else(|| panic!("{name} missing"));
        let got = (
            m.id,
            m.crc_extra,
            m.min_len,
            m.max_len,
            m.target_system_offset,
            m.target_component_offset,
        );
        assert_eq!(got, (id, crc, min, max, ts, tc), "{name}");
        assert_eq!(by_id(id), Some(m));
    }
}

#[test]
fn lookups() {
    let hb = by_name("HEARTBEAT").expect("HEARTBEAT");
    assert_eq!((hb.id, hb.crc_extra, hb.min_len), (0, 50, 9));
    let names: Vec<&str> = hb.fields.iter().map(|f| f.name).collect();
    assert_eq!(
        names,
        [
            "custom_mode",
            "type",
            "autopilot",
            "base_mode",
            "system_status",
            "mavlink_version"
        ]
    );
    assert!(by_id(255).is_none());
    assert!(by_id(u32::MAX).is_none());
    assert!(by_name("heartbeat").is_none());
    assert!(by_name("").is_none());
    assert!(by_name("HEARTBEAT ").is_none());
}

#[test]
fn manual_control_target_counts_as_target_system() {
    let m = by_name("MANUAL_CONTROL").expect("MANUAL_CONTROL");
    assert_eq!(m.id, 69);
    let target = m.fields.iter().find(|f| f.name == "target").expect("field");
    assert_eq!(m.target_system_offset, Some(10));
    assert_eq!(
        u16::from(m.target_system_offset.unwrap_or(0)),
        target.offset
    );
    assert_eq!(m.target_component_offset, None);
}

#[test]
fn field_lists_are_consistent() {
    for m in messages() {
        let mut next = 0usize;
        let mut in_extensions = false;
        let mut names = BTreeSet::new();
        for f in m.fields {
            assert_eq!(usize::from(f.offset), next, "{}.{} offset", m.name, f.name);
            next += f.size();
            assert!(names.insert(f.name), "{}.{} twice", m.name, f.name);
            if f.extension {
                in_extensions = true;
            } else {
                assert!(!in_extensions, "{}.{} after extensions", m.name, f.name);
            }
            if f.name == "target_system" || f.name == "target_component" {
                assert_eq!(f.size(), 1, "{}.{}", m.name, f.name);
            }
        }
        let base: usize = m
            .fields
            .iter()
            .filter(|f| !f.extension)
            .map(|f| f.size())
            .sum();
        assert_eq!(base, usize::from(m.min_len), "{} min_len", m.name);
        assert_eq!(next, usize::from(m.max_len), "{} max_len", m.name);
        // Base fields are ordered by element size, largest first.
        let sizes: Vec<usize> = m
            .fields
            .iter()
            .filter(|f| !f.extension)
            .map(|f| f.ty.size())
            .collect();
        assert!(sizes.windows(2).all(|w| w[0] >= w[1]), "{} order", m.name);
        // Target offsets point at the fields of that name.
        let offset_of = |name: &str| {
            m.fields
                .iter()
                .find(|f| f.name == name)
                .map(|f| u8::try_from(f.offset).expect("offset fits in u8"))
        };
        assert_eq!(
            m.target_component_offset,
            offset_of("target_component"),
            "{}",
            m.name
        );
        if m.name != "MANUAL_CONTROL" {
            assert_eq!(
                m.target_system_offset,
                offset_of("target_system"),
                "{}",
                m.name
            );
        }
    }
}

#[test]
fn tables_sorted_and_complete() {
    let all = messages();
    assert_eq!(all.len(), 325);
    assert!(all.windows(2).all(|w| w[0].id < w[1].id), "ids not sorted");
    let mut names: Vec<&str> = all.iter().map(|m| m.name).collect();
    names.sort_unstable();
    names.dedup();
    assert_eq!(names.len(), all.len(), "duplicate names");
    for m in all {
        assert!(std::ptr::eq(by_id(m.id).expect("by_id"), m));
        assert!(std::ptr::eq(by_name(m.name).expect("by_name"), m));
        assert!(m.min_len <= m.max_len, "{}", m.name);
    }
    // by_id agrees with the table for every id up to the largest one defined.
    let ids: BTreeSet<u32> = all.iter().map(|m| m.id).collect();
    let last = *ids.last().expect("non-empty");
    for id in 0..=last + 1 {
        assert_eq!(by_id(id).is_some(), ids.contains(&id), "by_id({id})");
    }
}
