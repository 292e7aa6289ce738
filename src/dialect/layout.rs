//! From a message as declared to its wire facts, as the MAVLink spec (and `mavgen`)
//! defines them: base fields sorted by element size, largest first (a stable sort, so
//! equal sizes keep their declared order), extension fields after them in declared
//! order; the lengths without and with extensions; and CRC_EXTRA over the message name
//! and each base field's type, name and array length, in wire order.

use crc::{CRC_16_MCRF4XX, Crc};

use super::FieldType;
use super::xml::{XmlField, XmlMessage};

/// The checksum MAVLink folds CRC_EXTRA from (X.25, as the frame checksum).
const X25: Crc<u16> = Crc::<u16>::new(&CRC_16_MCRF4XX);

/// The most fields a message may have (`mavgen`'s limit).
pub const MAX_FIELDS: usize = 64;

/// The most bytes a payload may have.
pub const MAX_PAYLOAD: usize = 255;

/// One field in wire order, with its offset.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LaidField {
    /// Field name.
    pub name: String,
    /// Element type.
    pub ty: FieldType,
    /// Array length; 0 for a scalar.
    pub array_len: u8,
    /// Byte offset in the full payload.
    pub offset: u16,
    /// An extension field.
    pub extension: bool,
}

/// A message's wire facts.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LaidOut {
    /// Message name.
    pub name: String,
    /// Message id.
    pub id: u32,
    /// CRC_EXTRA.
    pub crc_extra: u8,
    /// Payload length without extension fields.
    pub min_len: u8,
    /// Payload length with them.
    pub max_len: u8,
    /// Offset of a `uint8_t target_system` field.
    pub target_system_offset: Option<u8>,
    /// Offset of a `uint8_t target_component` field.
    pub target_component_offset: Option<u8>,
    /// Fields in wire order.
    pub fields: Vec<LaidField>,
}

/// Bytes of one field on the wire.
fn size_of(f: &XmlField) -> usize {
    f.ty.size() * usize::from(f.array_len.max(1))
}

/// The CRC_EXTRA of a message named `name` whose base fields in wire order are `base`.
pub fn crc_extra<'a>(name: &str, base: impl Iterator<Item = &'a XmlField>) -> u8 {
    let mut digest = X25.digest();
    digest.update(name.as_bytes());
    digest.update(b" ");
    for f in base {
        digest.update(f.type_name.as_bytes());
        digest.update(b" ");
        digest.update(f.name.as_bytes());
        digest.update(b" ");
        if f.array_len > 0 {
            digest.update(&[f.array_len]);
        }
    }
    let crc = digest.finalize();
    (crc & 0xff) as u8 ^ (crc >> 8) as u8
}

/// Lays out `m`, or says why it cannot be a MAVLink message.
pub fn lay_out(m: &XmlMessage) -> Result<LaidOut, String> {
    let name = &m.name;
    if m.fields.len() > MAX_FIELDS {
        return Err(format!(
            "message {name} has {} fields; MAVLink allows at most {MAX_FIELDS}",
            m.fields.len()
        ));
    }
    if !m.fields.iter().any(|f| !f.extension) {
        return Err(format!("message {name} has no fields before <extensions/>"));
    }
    for (i, f) in m.fields.iter().enumerate() {
        if m.fields[..i].iter().any(|g| g.name == f.name) {
            return Err(format!(
                "message {name}: field {} is declared twice",
                f.name
            ));
        }
    }
    let mut wire: Vec<&XmlField> = m.fields.iter().filter(|f| !f.extension).collect();
    // Stable: equal element sizes keep their declared order.
    wire.sort_by_key(|f| std::cmp::Reverse(f.ty.size()));
    let base = wire.len();
    wire.extend(m.fields.iter().filter(|f| f.extension));
    let mut fields = Vec::with_capacity(wire.len());
    let mut offset = 0usize;
    let mut min_len = 0usize;
    for (i, f) in wire.iter().enumerate() {
        fields.push(LaidField {
            name: f.name.clone(),
            ty: f.ty,
            array_len: f.array_len,
            offset: u16::try_from(offset).unwrap_or(u16::MAX),
            extension: f.extension,
        });
        offset += size_of(f);
        if i < base {
            min_len = offset;
        }
    }
    if offset > MAX_PAYLOAD {
        return Err(format!(
            "message {name} has a payload of {offset} bytes; MAVLink allows at most {MAX_PAYLOAD}"
        ));
    }
    let target = |field: &str| -> Result<Option<u8>, String> {
        match fields.iter().find(|f| f.name == field) {
            None => Ok(None),
            Some(f) if f.ty == FieldType::U8 && f.array_len == 0 => Ok(u8::try_from(f.offset).ok()),
            Some(_) => Err(format!(
                "message {name}: {field} must be a uint8_t (routing reads it as an address)"
            )),
        }
    };
    Ok(LaidOut {
        name: name.clone(),
        id: m.id,
        crc_extra: crc_extra(name, wire[..base].iter().copied()),
        min_len: u8::try_from(min_len).unwrap_or(u8::MAX),
        max_len: u8::try_from(offset).unwrap_or(u8::MAX),
        target_system_offset: target("target_system")?,
        target_component_offset: target("target_component")?,
        fields,
    })
}

#[cfg(test)]
mod tests {
    use super::super::{by_id, xml};
    use super::*;

    /// Every built-in message, written back as XML fields in wire order, lays out as the
    /// generated table says (the table came from another implementation).
    #[test]
    fn builtin_messages_lay_out_as_the_generated_table() {
        for info in super::super::messages() {
            let fields = info
                .fields
                .iter()
                .map(|f| XmlField {
                    name: f.name.to_string(),
                    ty: f.ty,
                    type_name: type_name(f.ty),
                    array_len: f.array_len,
                    extension: f.extension,
                })
                .collect();
            let m = xml::XmlMessage {
                name: info.name.to_string(),
                id: info.id,
                line: 1,
                fields,
                in_extensions: false,
            };
            let laid = lay_out(&m).expect("a built-in message lays out");
            let want = by_id(info.id).expect("built in");
            assert_eq!(laid.crc_extra, want.crc_extra, "{}", info.name);
            assert_eq!((laid.min_len, laid.max_len), (want.min_len, want.max_len));
            if info.name != "MANUAL_CONTROL" {
                assert_eq!(laid.target_system_offset, want.target_system_offset);
            }
            for (a, b) in laid.fields.iter().zip(info.fields) {
                assert_eq!(
                    (a.name.as_str(), a.offset),
                    (b.name, b.offset),
                    "{}",
                    info.name
                );
            }
        }
    }

    fn type_name(ty: FieldType) -> &'static str {
        match ty {
            FieldType::U8 => "uint8_t",
            FieldType::I8 => "int8_t",
            FieldType::U16 => "uint16_t",
            FieldType::I16 => "int16_t",
            FieldType::U32 => "uint32_t",
            FieldType::I32 => "int32_t",
            FieldType::U64 => "uint64_t",
            FieldType::I64 => "int64_t",
            FieldType::F32 => "float",
            FieldType::F64 => "double",
            FieldType::Char => "char",
        }
    }
}
