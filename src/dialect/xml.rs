//! Reading one MAVLink XML definition file (the format `mavgen` reads): its
//! `<include>`s and its `<message>`s with their fields in declaration order. Enums,
//! descriptions and the rest are checked for well-formedness only.
//!
//! The XML itself is read by `quick-xml` (a pull parser, no DOM: a 600 KiB `common.xml`
//! costs no tree); this module only walks its events. Everything here is outside input:
//! any problem is an [`XmlError`] with the line it is on, never a panic.

use std::fmt;

use quick_xml::Reader;
use quick_xml::events::{BytesStart, Event};

use super::FieldType;

/// A problem in one XML file, at a line (1-based).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct XmlError {
    /// The line of the problem.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for XmlError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}: {}", self.line, self.message)
    }
}

/// One `<field>` of a message, as declared.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct XmlField {
    /// Field name.
    pub name: String,
    /// Element type.
    pub ty: FieldType,
    /// The type's name as the CRC_EXTRA covers it (`uint8_t` for
    /// `uint8_t_mavlink_version`, `int8_t` for `array`).
    pub type_name: &'static str,
    /// Array length; 0 for a scalar.
    pub array_len: u8,
    /// Declared after `<extensions/>`.
    pub extension: bool,
}

/// One `<message>`, as declared.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct XmlMessage {
    /// Message name.
    pub name: String,
    /// Message id (24 bits).
    pub id: u32,
    /// The line of its `<message>` tag.
    pub line: usize,
    /// Fields in declaration order.
    pub fields: Vec<XmlField>,
    /// True once `<extensions/>` was seen: the fields after it are extensions.
    pub in_extensions: bool,
}

/// An `<include>` element: the file it names and its line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct XmlInclude {
    /// The path as written (relative to the including file's directory).
    pub path: String,
    /// The line of the `<include>` tag.
    pub line: usize,
}

/// What one file declares.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct XmlFile {
    /// Its includes, in order.
    pub includes: Vec<XmlInclude>,
    /// Its messages, in order.
    pub messages: Vec<XmlMessage>,
}

/// Where the reader is in the document: the elements that matter to it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Place {
    Mavlink,
    Messages,
    Message,
    Include,
    /// Anything else (enums, descriptions, a field's text).
    Other,
}

/// Line numbers of byte positions, counted on from the last position asked for (the
/// reader only moves forward, so a whole file costs one pass).
struct Lines<'t> {
    text: &'t [u8],
    at: usize,
    line: usize,
}

impl<'t> Lines<'t> {
    fn new(text: &'t str) -> Self {
        Lines {
            text: text.as_bytes(),
            at: 0,
            line: 1,
        }
    }

    /// Line number (1-based) of byte `at`.
    fn line_of(&mut self, at: u64) -> usize {
        let at = usize::try_from(at)
            .unwrap_or(usize::MAX)
            .min(self.text.len());
        if at < self.at {
            self.at = 0;
            self.line = 1;
        }
        let newlines = self.text[self.at..at]
            .iter()
            .filter(|&&b| b == b'\n')
            .count();
        self.line += newlines;
        self.at = at;
        self.line
    }
}

/// The reader's state between events.
#[derive(Default)]
struct Walker {
    file: XmlFile,
    stack: Vec<Place>,
    seen_root: bool,
    /// The text of the `<include>` being read, and its line.
    include: Option<(String, usize)>,
}

/// Reads one XML definition file.
pub fn parse(text: &str) -> Result<XmlFile, XmlError> {
    let mut reader = Reader::from_str(text);
    reader.config_mut().check_end_names = true;
    let mut w = Walker::default();
    let mut lines = Lines::new(text);
    loop {
        let line = lines.line_of(reader.buffer_position());
        let err = |message: String| XmlError { line, message };
        let event = match reader.read_event() {
            Ok(event) => event,
            Err(e) => {
                return Err(XmlError {
                    line: lines.line_of(reader.error_position()),
                    message: format!("malformed XML: {e}"),
                });
            }
        };
        match event {
            Event::Start(e) => {
                let place = w.open(&e, line, false).map_err(err)?;
                if place == Place::Include {
                    w.include = Some((String::new(), line));
                }
                w.stack.push(place);
            }
            Event::Empty(e) => {
                if w.open(&e, line, true).map_err(err)? == Place::Include {
                    return Err(err("an empty <include> names no file".to_string()));
                }
            }
            Event::End(_) => {
                if w.stack.pop() == Some(Place::Include) {
                    w.close_include()?;
                }
            }
            Event::Text(t) => {
                if let Some((path, _)) = w.include.as_mut() {
                    path.push_str(
                        &t.decode()
                            .map_err(|e| err(format!("malformed text: {e}")))?,
                    );
                }
            }
            Event::CData(t) => {
                if let Some((path, _)) = w.include.as_mut() {
                    path.push_str(
                        &t.decode()
                            .map_err(|e| err(format!("malformed text: {e}")))?,
                    );
                }
            }
            Event::GeneralRef(r) => {
                if let Some((path, _)) = w.include.as_mut() {
                    let name = r
                        .decode()
                        .map_err(|e| err(format!("malformed text: {e}")))?;
                    path.push(entity(&name).map_err(err)?);
                }
            }
            Event::Eof => {
                if !w.seen_root {
                    return Err(XmlError {
                        line: 1,
                        message: "no <mavlink> element: not a MAVLink definition file".to_string(),
                    });
                }
                if !w.stack.is_empty() {
                    return Err(err("the file ends inside an element".to_string()));
                }
                return Ok(w.file);
            }
            Event::Comment(_) | Event::Decl(_) | Event::PI(_) | Event::DocType(_) => {}
        }
    }
}

/// The character of a predefined entity reference (`&amp;` and friends).
fn entity(name: &str) -> Result<char, String> {
    Ok(match name {
        "amp" => '&',
        "lt" => '<',
        "gt" => '>',
        "quot" => '"',
        "apos" => '\'',
        other => return Err(format!("unknown entity '&{other};'")),
    })
}

impl Walker {
    /// An `</include>`: the file it named.
    fn close_include(&mut self) -> Result<(), XmlError> {
        let (path, line) = self.include.take().unwrap_or_default();
        let path = path.trim().to_string();
        if path.is_empty() {
            return Err(XmlError {
                line,
                message: "an empty <include> names no file".to_string(),
            });
        }
        self.file.includes.push(XmlInclude { path, line });
        Ok(())
    }

    /// An element opens (at `line`; `empty` for `<x/>`): what it is, and what it adds.
    fn open(&mut self, e: &BytesStart<'_>, line: usize, empty: bool) -> Result<Place, String> {
        let name = e.name();
        let tag = std::str::from_utf8(name.as_ref()).unwrap_or("?");
        Ok(match (self.stack.last().copied(), tag) {
            (None, "mavlink") if !self.seen_root => {
                self.seen_root = true;
                Place::Mavlink
            }
            (None, "mavlink") => return Err("a second <mavlink> element".to_string()),
            (None, other) => {
                return Err(format!(
                    "the root element is <{other}>, not <mavlink>: not a MAVLink definition file"
                ));
            }
            (Some(Place::Mavlink), "include") => Place::Include,
            (Some(Place::Mavlink), "messages") => Place::Messages,
            (Some(Place::Messages), "message") => {
                let message = message(e, line)?;
                if empty {
                    return Err(format!("message {} has no fields", message.name));
                }
                self.file.messages.push(message);
                Place::Message
            }
            (Some(Place::Message), "extensions") => {
                let m = self.current()?;
                if m.in_extensions {
                    return Err(format!("message {}: a second <extensions/>", m.name));
                }
                m.in_extensions = true;
                Place::Other
            }
            (Some(Place::Message), "field") => {
                let m = self.current()?;
                let f = field(e, m.in_extensions)
                    .map_err(|why| format!("message {}: {why}", m.name))?;
                m.fields.push(f);
                Place::Other
            }
            _ => Place::Other,
        })
    }

    /// The message being read.
    fn current(&mut self) -> Result<&mut XmlMessage, String> {
        self.file
            .messages
            .last_mut()
            .ok_or_else(|| "an element outside a message".to_string())
    }
}

/// A `<message name=".." id="..">` tag at `line`.
fn message(e: &BytesStart<'_>, line: usize) -> Result<XmlMessage, String> {
    let name = attribute(e, "name")?.ok_or("a <message> without a name")?;
    check_name(&name, "message")?;
    let id_text = attribute(e, "id")?.ok_or_else(|| format!("message {name} has no id"))?;
    let id = parse_id(&id_text).ok_or_else(|| {
        format!("message {name}: id '{id_text}' is not a number from 0 to 16777215")
    })?;
    Ok(XmlMessage {
        name,
        id,
        line,
        fields: Vec::new(),
        in_extensions: false,
    })
}

/// A `<field type=".." name="..">` tag.
fn field(e: &BytesStart<'_>, extension: bool) -> Result<XmlField, String> {
    let name = attribute(e, "name")?.ok_or("a <field> without a name")?;
    check_name(&name, "field")?;
    let ty = attribute(e, "type")?.ok_or_else(|| format!("field {name} has no type"))?;
    let (ty, type_name, array_len) =
        field_type(&ty).map_err(|why| format!("field {name}: {why}"))?;
    Ok(XmlField {
        name,
        ty,
        type_name,
        array_len,
        extension,
    })
}

/// The value of attribute `key`, unescaped.
fn attribute(e: &BytesStart<'_>, key: &str) -> Result<Option<String>, String> {
    for a in e.attributes() {
        let a = a.map_err(|why| format!("malformed attribute: {why}"))?;
        if a.key.as_ref() == key.as_bytes() {
            let v = a
                .normalized_value(quick_xml::XmlVersion::Implicit1_0)
                .map_err(|why| format!("malformed attribute {key}: {why}"))?;
            return Ok(Some(v.trim().to_string()));
        }
    }
    Ok(None)
}

/// A message id: decimal, 0 to 2^24 - 1.
fn parse_id(text: &str) -> Option<u32> {
    let id: u32 = text.parse().ok()?;
    (id < (1 << 24)).then_some(id)
}

/// Names are C identifiers (messages upper case by convention, which rules rely on).
fn check_name(name: &str, what: &str) -> Result<(), String> {
    let ok = !name.is_empty()
        && name.len() <= 64
        && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_')
        && !name.as_bytes().first().is_some_and(u8::is_ascii_digit);
    if !ok {
        return Err(format!(
            "{what} name '{name}' is not a name (letters, digits and '_', at most 64)"
        ));
    }
    if what == "message" && name.bytes().any(|b| b.is_ascii_lowercase()) {
        return Err(format!(
            "message name '{name}' has lower-case letters: MAVLink message names are upper case"
        ));
    }
    Ok(())
}

/// A field's type: element type, the name the CRC_EXTRA covers, array length.
fn field_type(text: &str) -> Result<(FieldType, &'static str, u8), String> {
    let (base, array_len) = match text.split_once('[') {
        None => (text, 0),
        Some((base, rest)) => {
            let n = rest
                .strip_suffix(']')
                .and_then(|n| n.parse::<u16>().ok())
                .filter(|n| (1..=255).contains(n))
                .ok_or_else(|| format!("type '{text}': an array length is 1 to 255"))?;
            (base, n as u8)
        }
    };
    let (ty, name) = match base {
        "float" => (FieldType::F32, "float"),
        "double" => (FieldType::F64, "double"),
        "char" => (FieldType::Char, "char"),
        "int8_t" | "int8" => (FieldType::I8, "int8_t"),
        "array" if array_len > 0 => (FieldType::I8, "int8_t"),
        "uint8_t" | "uint8" => (FieldType::U8, "uint8_t"),
        "uint8_t_mavlink_version" if array_len == 0 => (FieldType::U8, "uint8_t"),
        "int16_t" | "int16" => (FieldType::I16, "int16_t"),
        "uint16_t" | "uint16" => (FieldType::U16, "uint16_t"),
        "int32_t" | "int32" => (FieldType::I32, "int32_t"),
        "uint32_t" | "uint32" => (FieldType::U32, "uint32_t"),
        "int64_t" | "int64" => (FieldType::I64, "int64_t"),
        "uint64_t" | "uint64" => (FieldType::U64, "uint64_t"),
        _ => return Err(format!("unknown type '{text}'")),
    };
    Ok((ty, name, array_len))
}
