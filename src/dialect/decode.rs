//! Decoding message fields by name from a payload, using the dialect's field layout,
//! and rendering them as JSON.
//!
//! A payload may be shorter than the message (MAVLink 2 drops trailing zero bytes: the
//! missing bytes read as zero) or longer (a newer dialect's extension fields: the bytes
//! past the known fields are ignored). Neither panics.

use std::fmt::Write as _;

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

/// Appends `s` to `out` as a JSON string literal.
pub fn write_json_string(out: &mut String, s: &str) {
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if (c as u32) < 0x20 => {
                let _ = write!(out, "\\u{:04x}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
}

/// Appends `value` as JSON. Non-finite floats, which JSON cannot express, become `null`.
pub fn write_json_value(out: &mut String, value: &Value) {
    match value {
        Value::Int(v) => {
            let _ = write!(out, "{v}");
        }
        Value::UInt(v) => {
            let _ = write!(out, "{v}");
        }
        Value::Float(v) if v.is_finite() => {
            // Debug keeps a decimal point or exponent, so the value reads back as a float.
            let _ = write!(out, "{v:?}");
        }
        Value::Float(_) => out.push_str("null"),
        Value::Text(s) => write_json_string(out, s),
        Value::Array(items) => {
            out.push('[');
            for (i, item) in items.iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                write_json_value(out, item);
            }
            out.push(']');
        }
    }
}

/// Appends element `i` of `field` from `payload` as JSON, without building a [`Value`].
/// `float` fields are written in their shortest form that reads back as the same
/// `float` (`0.1`, not `0.10000000149011612`).
fn write_json_element(out: &mut String, field: &Field, payload: &[u8], i: usize) {
    match element(field, payload, i) {
        Value::Float(v) if field.ty == FieldType::F32 && v.is_finite() => {
            out.push_str(ryu::Buffer::new().format_finite(v as f32));
        }
        Value::Float(v) if v.is_finite() => out.push_str(ryu::Buffer::new().format_finite(v)),
        Value::UInt(v) => out.push_str(itoa::Buffer::new().format(v)),
        Value::Int(v) => out.push_str(itoa::Buffer::new().format(v)),
        other => write_json_value(out, &other),
    }
}

/// Appends every field of `info` decoded from `payload` as one JSON object
/// (`{"name":value,...}`, wire order). Strings and arrays as in [`decode_field`].
pub fn write_json_fields(out: &mut String, info: &MessageInfo, payload: &[u8]) {
    out.push('{');
    for (n, field) in info.fields.iter().enumerate() {
        if n > 0 {
            out.push(',');
        }
        out.push('"');
        out.push_str(field.name);
        out.push_str("\":");
        if field.array_len == 0 {
            write_json_element(out, field, payload, 0);
        } else if field.ty == FieldType::Char {
            write_json_value(out, &decode_field(field, payload));
        } else {
            out.push('[');
            for i in 0..field.array_len as usize {
                if i > 0 {
                    out.push(',');
                }
                write_json_element(out, field, payload, i);
            }
            out.push(']');
        }
    }
    out.push('}');
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::by_name;

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
        let mut out = String::new();
        write_json_fields(&mut out, by_name("PARAM_VALUE").expect("known"), &p);
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
        let mut out = String::new();
        write_json_string(&mut out, "a\"b\\c\u{1}");
        assert_eq!(out, r#""a\"b\\c\u0001""#);
        let mut out = String::new();
        write_json_value(
            &mut out,
            &Value::Array(vec![Value::Float(f64::NAN), Value::Float(2.0)]),
        );
        assert_eq!(out, "[null,2.0]");
    }

    #[test]
    fn bytes_past_the_known_fields_are_ignored() {
        // HEARTBEAT (9 known bytes) followed by 246 bytes of a newer dialect.
        let info = by_name("HEARTBEAT").expect("known");
        let known = [1u8, 0, 0, 0, 2, 3, 0x51, 4, 3];
        let mut longer = known.to_vec();
        longer.resize(255, 0xff);
        let (mut a, mut b) = (String::new(), String::new());
        write_json_fields(&mut a, info, &known);
        write_json_fields(&mut b, info, &longer);
        assert_eq!(a, b);
        assert!(a.starts_with(r#"{"custom_mode":1,"type":2,"#), "{a}");
    }
}
