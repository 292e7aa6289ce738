//! Decoding message fields by name from a payload, using the dialect's field layout,
//! and handing them to a serializer (`serde_json` writes them as JSON).
//!
//! A payload may be shorter than the message (MAVLink 2 drops trailing zero bytes: the
//! missing bytes read as zero) or longer (a newer dialect's extension fields: the bytes
//! past the known fields are ignored). Neither panics.

use serde::ser::{Serialize, SerializeMap, SerializeSeq, Serializer};

use super::{Field, FieldType, MessageInfo};

/// One decoded field value.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// Any signed integer type.
    Int(i64),
    /// Any unsigned integer type.
    UInt(u64),
    /// `float` or `double` (a `float` widened exactly).
    Float(f64),
    /// A `char[N]` array: the bytes up to the first NUL, as text.
    Text(String),
    /// Any other array.
    Array(Vec<Value>),
}

/// Reads element `i` of `field` from a zero-padded payload.
fn element(field: &Field, payload: &[u8], i: usize) -> Value {
    let size = field.ty.size();
    let at = field.offset as usize + i * size;
    let mut b = [0u8; 8];
    // A v2 payload may end inside a field: the missing high bytes read as zero.
    if let Some(src) = payload.get(at..) {
        let n = src.len().min(size);
        b[..n].copy_from_slice(&src[..n]);
    }
    match field.ty {
        FieldType::U8 | FieldType::Char => Value::UInt(u64::from(b[0])),
        FieldType::I8 => Value::Int(i64::from(b[0] as i8)),
        FieldType::U16 => Value::UInt(u64::from(u16::from_le_bytes([b[0], b[1]]))),
        FieldType::I16 => Value::Int(i64::from(i16::from_le_bytes([b[0], b[1]]))),
        FieldType::U32 => Value::UInt(u64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))),
        FieldType::I32 => Value::Int(i64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]]))),
        FieldType::F32 => Value::Float(f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))),
        FieldType::U64 => Value::UInt(u64::from_le_bytes(b)),
        FieldType::I64 => Value::Int(i64::from_le_bytes(b)),
        FieldType::F64 => Value::Float(f64::from_le_bytes(b)),
    }
}

/// Decodes `field` from `payload`. Bytes beyond the payload (v2 truncation) read as zero;
/// bytes beyond the field are not looked at.
pub fn decode_field(field: &Field, payload: &[u8]) -> Value {
    if field.array_len == 0 {
        return element(field, payload, 0);
    }
    if field.ty == FieldType::Char {
        let start = (field.offset as usize).min(payload.len());
        let end = (field.offset as usize + field.array_len as usize).min(payload.len());
        let bytes = &payload[start..end];
        let text = bytes.split(|&b| b == 0).next().unwrap_or(&[]);
        return Value::Text(String::from_utf8_lossy(text).into_owned());
    }
    Value::Array(
        (0..field.array_len as usize)
            .map(|i| element(field, payload, i))
            .collect(),
    )
}

impl Serialize for Value {
    /// JSON's forms: numbers, a string, an array; a non-finite float (which JSON cannot
    /// express) becomes `null`.
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Value::Int(v) => s.serialize_i64(*v),
            Value::UInt(v) => s.serialize_u64(*v),
            Value::Float(v) => s.serialize_f64(*v),
            Value::Text(t) => s.serialize_str(t),
            Value::Array(items) => s.collect_seq(items),
        }
    }
}

/// Every field of a message decoded from its payload, for a serializer: one object
/// (`{"name":value,...}`, wire order), strings and arrays as in [`decode_field`]. `float`
/// fields are written in their shortest form that reads back as the same `float` (`0.1`,
/// not `0.10000000149011612`). Nothing is decoded until it is serialized.
#[derive(Debug, Clone, Copy)]
pub struct Fields<'a> {
    /// The message.
    pub info: &'a MessageInfo,
    /// Its payload (possibly truncated or longer than the known fields).
    pub payload: &'a [u8],
}

impl Serialize for Fields<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(self.info.fields.len()))?;
        for field in self.info.fields {
            let one = Element {
                field,
                payload: self.payload,
            };
            if field.array_len == 0 {
                map.serialize_entry(field.name, &one.at(0))?;
            } else if field.ty == FieldType::Char {
                map.serialize_entry(field.name, &decode_field(field, self.payload))?;
            } else {
                map.serialize_entry(field.name, &one)?;
            }
        }
        map.end()
    }
}

/// One field of a payload; serialized as the array of its elements.
#[derive(Clone, Copy)]
struct Element<'a> {
    field: &'a Field,
    payload: &'a [u8],
}

/// Element `i` of a field, serialized as its wire type says (a `float` as an `f32`).
struct At<'a>(Element<'a>, usize);

impl<'a> Element<'a> {
    fn at(self, i: usize) -> At<'a> {
        At(self, i)
    }
}

impl Serialize for Element<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let n = usize::from(self.field.array_len);
        let mut seq = s.serialize_seq(Some(n))?;
        for i in 0..n {
            seq.serialize_element(&self.at(i))?;
        }
        seq.end()
    }
}

impl Serialize for At<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let At(e, i) = self;
        match element(e.field, e.payload, *i) {
            Value::Float(v) if e.field.ty == FieldType::F32 => s.serialize_f32(v as f32),
            other => other.serialize(s),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::by_name;

    fn json(info: &MessageInfo, payload: &[u8]) -> String {
        serde_json::to_string(&Fields { info, payload }).expect("serializes")
    }

    fn field(msg: &str, name: &str) -> &'static Field {
        by_name(msg)
            .and_then(|m| m.fields.iter().find(|f| f.name == name))
            .expect("field exists")
    }

    #[test]
    fn scalars_arrays_and_text() {
        // PARAM_VALUE: param_value f32 @0, param_count u16 @4, param_index u16 @6,
        // param_id char[16] @8, param_type u8 @24.
        let mut p = vec![0u8; 25];
        p[..4].copy_from_slice(&1.5f32.to_le_bytes());
        p[4..6].copy_from_slice(&300u16.to_le_bytes());
        p[8..13].copy_from_slice(b"SYSID");
        p[24] = 9;
        assert_eq!(
            decode_field(field("PARAM_VALUE", "param_value"), &p),
            Value::Float(1.5)
        );
        assert_eq!(
            decode_field(field("PARAM_VALUE", "param_count"), &p),
            Value::UInt(300)
        );
        assert_eq!(
            decode_field(field("PARAM_VALUE", "param_id"), &p),
            Value::Text("SYSID".into())
        );
        let out = json(by_name("PARAM_VALUE").expect("known"), &p);
        assert_eq!(
            out,
            r#"{"param_value":1.5,"param_count":300,"param_index":0,"param_id":"SYSID","param_type":9}"#
        );
    }

    #[test]
    fn truncated_payload_reads_zero_and_signed_types_sign_extend() {
        // ATTITUDE roll f32 @4; GLOBAL_POSITION_INT vz i16 @24.
        assert_eq!(
            decode_field(field("ATTITUDE", "roll"), &[1, 2]),
            Value::Float(0.0)
        );
        let mut p = vec![0u8; 28];
        p[24..26].copy_from_slice(&(-5i16).to_le_bytes());
        assert_eq!(
            decode_field(field("GLOBAL_POSITION_INT", "vz"), &p),
            Value::Int(-5)
        );
    }

    #[test]
    fn json_strings_are_escaped_and_nan_is_null() {
        let text = |v: &Value| serde_json::to_string(v).expect("serializes");
        assert_eq!(
            text(&Value::Text("a\"b\\c\u{1}".into())),
            r#""a\"b\\c\u0001""#
        );
        assert_eq!(
            text(&Value::Array(vec![
                Value::Float(f64::NAN),
                Value::Float(2.0)
            ])),
            "[null,2.0]"
        );
        // A float field keeps its shortest f32 form; an array field is an array.
        let mut p = vec![0u8; 28];
        p[4..8].copy_from_slice(&0.1f32.to_le_bytes());
        p[8..12].copy_from_slice(&f32::NAN.to_le_bytes());
        let att = json(by_name("ATTITUDE").expect("known"), &p);
        assert!(att.contains(r#""roll":0.1,"pitch":null,"#), "{att}");
        let mut p = vec![0u8; 72];
        p[12..16].copy_from_slice(&0.5f32.to_le_bytes());
        let cov = json(by_name("ATTITUDE_QUATERNION_COV").expect("known"), &p);
        assert!(cov.contains(r#""q":[0.0,0.5,0.0,0.0],"#), "{cov}");
    }

    #[test]
    fn bytes_past_the_known_fields_are_ignored() {
        // HEARTBEAT (9 known bytes) followed by 246 bytes of a newer dialect.
        let info = by_name("HEARTBEAT").expect("known");
        let known = [1u8, 0, 0, 0, 2, 3, 0x51, 4, 3];
        let mut longer = known.to_vec();
        longer.resize(255, 0xff);
        let (a, b) = (json(info, &known), json(info, &longer));
        assert_eq!(a, b);
        assert!(a.starts_with(r#"{"custom_mode":1,"type":2,"#), "{a}");
    }
}
