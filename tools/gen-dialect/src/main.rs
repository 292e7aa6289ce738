//! Generates mavtables' `src/dialect/ardupilotmega.rs` from the official MAVLink XML
//! shipped inside the `mavlink` crate, using its runtime (`dialect-dynamic`) parser.
//!
//! Usage (from the repository root):
//!
//! ```text
//! cargo run --manifest-path tools/gen-dialect/Cargo.toml --release [-- --check] [--xml PATH] [--out PATH]
//! ```
//!
//! Without `--xml` the XML is located through `cargo metadata` (the registry copy of the
//! `mavlink` package this tool depends on). `--check` regenerates into a scratch file and
//! fails if the committed table differs.

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::{env, fs};

use mavlink::dialects::dynamic::{DynamicDialect, DynamicField, DynamicMessageDefinition};

/// Dialect (XML file stem) the table is generated from.
const DIALECT: &str = "ardupilotmega";

/// The one command that regenerates the table, written into the file header.
const REGEN_COMMAND: &str = "cargo run --manifest-path tools/gen-dialect/Cargo.toml --release";

/// Project decision: fields that count as the target system although they are not
/// called `target_system` (message name, field name).
const EXTRA_TARGET_SYSTEM_FIELDS: &[(&str, &str)] = &[("MANUAL_CONTROL", "target")];

/// Known facts checked before anything is written:
/// (name, id, crc_extra, min_len, max_len, target_system, target_component).
type SpotCheck = (&'static str, u32, u8, u8, u8, Option<u8>, Option<u8>);
const SPOT_CHECKS: &[SpotCheck] = &[
    ("HEARTBEAT", 0, 50, 9, 9, None, None),
    ("SYS_STATUS", 1, 124, 31, 43, None, None),
    ("COMMAND_LONG", 76, 152, 33, 33, Some(30), Some(31)),
    ("MISSION_ITEM", 39, 254, 37, 38, Some(32), Some(33)),
    ("ENCAPSULATED_DATA", 131, 223, 255, 255, None, None),
    ("TIMESYNC", 111, 34, 16, 18, Some(16), Some(17)),
    ("COMMAND_ACK", 77, 143, 3, 10, Some(8), Some(9)),
    ("MANUAL_CONTROL", 69, 243, 11, 30, Some(10), None),
];

/// Our `FieldType` variant for a MAVLink primitive type, and its element size.
fn field_type(primitive: &str) -> (&'static str, usize) {
    match primitive {
        "uint8_t" | "uint8_t_mavlink_version" => ("U8", 1),
        "int8_t" => ("I8", 1),
        "char" => ("Char", 1),
        "uint16_t" => ("U16", 2),
        "int16_t" => ("I16", 2),
        "uint32_t" => ("U32", 4),
        "int32_t" => ("I32", 4),
        "float" => ("F32", 4),
        "uint64_t" => ("U64", 8),
        "int64_t" => ("I64", 8),
        "double" => ("F64", 8),
        other => panic!("unknown MAVLink primitive type {other:?}"),
    }
}

/// One field, reduced to what the table stores.
struct FieldRow {
    name: String,
    ty: &'static str,
    elem_size: usize,
    array_len: usize,
    offset: usize,
    size: usize,
    extension: bool,
}

/// One message, reduced to what the table stores.
struct MessageRow {
    id: u32,
    name: String,
    crc_extra: u8,
    min_len: u8,
    max_len: u8,
    target_system: Option<u8>,
    target_component: Option<u8>,
    fields: Vec<FieldRow>,
}

fn field_row(msg: &str, f: &DynamicField) -> FieldRow {
    let (ty, elem_size) = field_type(f.primitive_type());
    let size = f.encoded_size();
    // The dynamic API does not expose array-ness directly; a length-1 array would be
    // indistinguishable from a scalar by size alone, so look at the parsed type.
    let debug = format!("{f:?}");
    let is_array = debug.contains("mavtype: Array(") || debug.contains("mavtype: CharArray(");
    assert!(
        size.is_multiple_of(elem_size),
        "{msg}.{}: size {size} is not a multiple of {elem_size}",
        f.name()
    );
    let array_len = if is_array {
        let n = size / elem_size;
        assert!(
            (1..=255).contains(&n),
            "{msg}.{}: array length {n} out of range",
            f.name()
        );
        n
    } else {
        assert_eq!(
            size,
            elem_size,
            "{msg}.{}: scalar of unexpected size",
            f.name()
        );
        0
    };
    // The parser renames the XML field `type` (a Rust keyword) to `mavtype`; undo that.
    let name = match f.name() {
        "mavtype" => "type",
        other => other,
    };
    FieldRow {
        name: name.to_owned(),
        ty,
        elem_size,
        array_len,
        offset: f.offset(),
        size,
        extension: f.is_extension(),
    }
}

/// Offset of a single-byte scalar field used as a target address.
fn target_offset(msg: &str, field: &FieldRow) -> u8 {
    assert!(
        field.ty == "U8" && field.array_len == 0,
        "{msg}.{}: target field is not a uint8_t scalar",
        field.name
    );
    u8::try_from(field.offset).expect("target offset fits in u8")
}

fn message_row(def: &DynamicMessageDefinition) -> MessageRow {
    let name = def.name().to_owned();
    let mut fields: Vec<FieldRow> = def.fields().iter().map(|f| field_row(&name, f)).collect();
    fields.sort_by_key(|f| f.offset);

    // Layout sanity: contiguous, base fields first (by element size, descending), then extensions.
    let mut next = 0;
    let mut seen_extension = false;
    let mut last_base_elem = usize::MAX;
    for f in &fields {
        assert_eq!(f.offset, next, "{name}.{}: offsets not contiguous", f.name);
        next += f.size;
        if f.extension {
            seen_extension = true;
        } else {
            assert!(
                !seen_extension,
                "{name}.{}: base field after an extension",
                f.name
            );
            assert!(
                f.elem_size <= last_base_elem,
                "{name}.{}: base fields not sorted by size",
                f.name
            );
            last_base_elem = f.elem_size;
        }
    }
    let base: usize = fields.iter().filter(|f| !f.extension).map(|f| f.size).sum();
    assert_eq!(base, def.base_payload_len(), "{name}: base length mismatch");
    assert_eq!(next, def.encoded_size(), "{name}: full length mismatch");

    let mut target_system = None;
    let mut target_component = None;
    for f in &fields {
        let is_ts = f.name == "target_system"
            || EXTRA_TARGET_SYSTEM_FIELDS.contains(&(name.as_str(), f.name.as_str()));
        if is_ts {
            assert!(target_system.is_none(), "{name}: two target system fields");
            target_system = Some(target_offset(&name, f));
        }
        if f.name == "target_component" {
            assert!(
                target_component.is_none(),
                "{name}: two target_component fields"
            );
            target_component = Some(target_offset(&name, f));
        }
    }

    MessageRow {
        id: def.id(),
        crc_extra: def.extra_crc(),
        min_len: u8::try_from(base).expect("min_len fits in u8"),
        max_len: u8::try_from(next).expect("max_len fits in u8"),
        target_system,
        target_component,
        fields,
        name,
    }
}

fn spot_check(rows: &[MessageRow]) {
    for &(name, id, crc, min, max, ts, tc) in SPOT_CHECKS {
        let m = rows
            .iter()
            .find(|m| m.name == name)
            .unwrap_or_else(|| panic!("spot check: {name} missing"));
        let got = (
            m.id,
            m.crc_extra,
            m.min_len,
            m.max_len,
            m.target_system,
            m.target_component,
        );
        assert_eq!(
            got,
            (id, crc, min, max, ts, tc),
            "spot check failed for {name}"
        );
    }
}

fn render(rows: &[MessageRow], source: &str) -> String {
    let mut out = String::new();
    let w = &mut out;
    let used: BTreeSet<&str> = rows
        .iter()
        .flat_map(|m| m.fields.iter().map(|f| f.ty))
        .collect();

    writeln!(w, "// Generated by tools/gen-dialect from the MAVLink XML").unwrap();
    writeln!(w, "//     {source}").unwrap();
    writeln!(
        w,
        "// Do not edit by hand. Regenerate from the repository root with:"
    )
    .unwrap();
    writeln!(w, "//     {REGEN_COMMAND}").unwrap();
    writeln!(w).unwrap();
    writeln!(
        w,
        "//! The `{DIALECT}` message table ({} messages).",
        rows.len()
    )
    .unwrap();
    writeln!(w).unwrap();
    let variants: Vec<&str> = used.iter().copied().collect();
    writeln!(w, "use super::FieldType::{{{}}};", variants.join(", ")).unwrap();
    writeln!(w, "use super::{{Field, FieldType, MessageInfo}};").unwrap();
    writeln!(w).unwrap();
    writeln!(w, "/// A MAVLink 1 (base) field.").unwrap();
    writeln!(
        w,
        "const fn base(name: &'static str, ty: FieldType, array_len: u8, offset: u16) -> Field {{"
    )
    .unwrap();
    writeln!(
        w,
        "Field {{ name, ty, array_len, offset, extension: false }}\n}}\n"
    )
    .unwrap();
    writeln!(w, "/// A MAVLink 2 extension field.").unwrap();
    writeln!(
        w,
        "const fn ext(name: &'static str, ty: FieldType, array_len: u8, offset: u16) -> Field {{"
    )
    .unwrap();
    writeln!(
        w,
        "Field {{ name, ty, array_len, offset, extension: true }}\n}}\n"
    )
    .unwrap();

    for m in rows {
        writeln!(w, "static F_{}: [Field; {}] = [", m.name, m.fields.len()).unwrap();
        for f in &m.fields {
            let ctor = if f.extension { "ext" } else { "base" };
            writeln!(
                w,
                "{ctor}({:?}, {}, {}, {}),",
                f.name, f.ty, f.array_len, f.offset
            )
            .unwrap();
        }
        writeln!(w, "];\n").unwrap();
    }

    let opt = |o: Option<u8>| o.map_or_else(|| "None".to_owned(), |v| format!("Some({v})"));
    writeln!(w, "/// All messages, sorted by id.").unwrap();
    writeln!(
        w,
        "pub(super) static MESSAGES: [MessageInfo; {}] = [",
        rows.len()
    )
    .unwrap();
    for m in rows {
        writeln!(
            w,
            "MessageInfo {{ id: {}, name: {:?}, crc_extra: {}, min_len: {}, max_len: {}, \
             target_system_offset: {}, target_component_offset: {}, fields: &F_{} }},",
            m.id,
            m.name,
            m.crc_extra,
            m.min_len,
            m.max_len,
            opt(m.target_system),
            opt(m.target_component),
            m.name
        )
        .unwrap();
    }
    writeln!(w, "];\n").unwrap();

    let mut by_name: Vec<(&str, usize)> = rows
        .iter()
        .enumerate()
        .map(|(i, m)| (m.name.as_str(), i))
        .collect();
    by_name.sort_unstable();
    writeln!(
        w,
        "/// `(name, index into MESSAGES)`, sorted by name (byte order)."
    )
    .unwrap();
    writeln!(
        w,
        "pub(super) static BY_NAME: [(&str, u16); {}] = [",
        rows.len()
    )
    .unwrap();
    for (name, i) in by_name {
        writeln!(w, "({name:?}, {i}),").unwrap();
    }
    writeln!(w, "];\n").unwrap();

    writeln!(w, "/// Index into [`MESSAGES`] of message `id`.").unwrap();
    writeln!(
        w,
        "pub(super) fn index_of(id: u32) -> Option<usize> {{\nmatch id {{"
    )
    .unwrap();
    for (i, m) in rows.iter().enumerate() {
        writeln!(w, "{} => Some({i}),", m.id).unwrap();
    }
    writeln!(w, "_ => None,\n}}\n}}").unwrap();
    out.push_str(TESTS);
    out
}

/// Unit tests appended to the generated module: they see the private tables.
const TESTS: &str = r#"
#[cfg(test)]
mod tests {
    use super::{BY_NAME, MESSAGES, index_of};

    #[test]
    fn by_name_is_sorted_and_a_permutation() {
        assert!(BY_NAME.windows(2).all(|w| w[0].0 < w[1].0));
        let mut seen = [false; MESSAGES.len()];
        for &(name, i) in &BY_NAME {
            let i = usize::from(i);
            assert_eq!(MESSAGES[i].name, name);
            assert!(!seen[i]);
            seen[i] = true;
        }
    }

    #[test]
    fn index_of_agrees_with_messages() {
        assert!(MESSAGES.windows(2).all(|w| w[0].id < w[1].id));
        for (i, m) in MESSAGES.iter().enumerate() {
            assert_eq!(index_of(m.id), Some(i));
        }
        let last = MESSAGES[MESSAGES.len() - 1].id;
        let defined = (0..=last + 1).filter(|&id| index_of(id).is_some()).count();
        assert_eq!(defined, MESSAGES.len());
    }
}
"#;

/// Locates `message_definitions/v1.0/<DIALECT>.xml` inside the `mavlink` package this
/// tool depends on, via `cargo metadata`. Returns the path and a short, machine
/// independent description of it (`mavlink-<version>/...`).
fn locate_xml(manifest_dir: &Path) -> (PathBuf, String) {
    let cargo = env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let output = Command::new(cargo)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--locked",
            "--manifest-path",
        ])
        .arg(manifest_dir.join("Cargo.toml"))
        .output()
        .expect("failed to run `cargo metadata`");
    assert!(
        output.status.success(),
        "`cargo metadata` failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let meta: serde_json::Value =
        serde_json::from_slice(&output.stdout).expect("`cargo metadata` printed invalid JSON");
    let packages = meta["packages"]
        .as_array()
        .expect("metadata has no packages");
    let pkg = packages
        .iter()
        .find(|p| p["name"] == "mavlink")
        .expect("the mavlink package is not in the dependency graph");
    let version = pkg["version"]
        .as_str()
        .expect("mavlink package has no version");
    let manifest = PathBuf::from(pkg["manifest_path"].as_str().expect("no manifest_path"));
    let rel = format!("mavlink/message_definitions/v1.0/{DIALECT}.xml");
    let path = manifest.parent().expect("manifest has a parent").join(&rel);
    (path, format!("mavlink-{version}/{rel}"))
}

/// The parser reports XML fields named `type` as `mavtype`; make sure no XML field is
/// literally called `mavtype`, so mapping it back is unambiguous.
fn assert_no_literal_mavtype(xml: &Path) {
    let dir = xml.parent().expect("XML path has a parent");
    for entry in fs::read_dir(dir).expect("cannot list the XML directory") {
        let path = entry.expect("cannot read directory entry").path();
        if path.extension().is_some_and(|e| e == "xml") {
            let text = fs::read_to_string(&path).expect("cannot read XML file");
            assert!(
                !text.contains("name=\"mavtype\""),
                "{} has a field literally named mavtype",
                path.display()
            );
        }
    }
}

fn rustfmt(path: &Path) {
    let status = Command::new("rustfmt")
        .args(["--edition", "2024"])
        .arg(path)
        .status()
        .expect("failed to run rustfmt");
    assert!(status.success(), "rustfmt failed on {}", path.display());
}

fn main() -> ExitCode {
    let manifest_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let repo_root = manifest_dir
        .join("../..")
        .canonicalize()
        .expect("cannot resolve the repository root");
    let mut xml: Option<PathBuf> = None;
    let mut out = repo_root.join("src/dialect").join(format!("{DIALECT}.rs"));
    let mut check = false;
    let mut args = env::args_os().skip(1);
    while let Some(arg) = args.next() {
        match arg.to_str() {
            Some("--check") => check = true,
            Some("--xml") => xml = Some(args.next().expect("--xml needs a path").into()),
            Some("--out") => out = args.next().expect("--out needs a path").into(),
            _ => {
                eprintln!("usage: gen-dialect [--check] [--xml PATH] [--out PATH]");
                return ExitCode::from(2);
            }
        }
    }
    let (xml, source) = match xml {
        Some(p) => {
            let shown = p.display().to_string();
            (p, shown)
        }
        None => locate_xml(&manifest_dir),
    };

    assert_no_literal_mavtype(&xml);
    let dialect = DynamicDialect::from_xml_file(&xml)
        .unwrap_or_else(|e| panic!("cannot load {}: {e}", xml.display()));
    let rows: Vec<MessageRow> = dialect.message_definitions().map(message_row).collect();
    assert!(
        rows.windows(2).all(|w| w[0].id < w[1].id),
        "ids not strictly increasing"
    );
    assert!(
        u16::try_from(rows.len()).is_ok(),
        "too many messages for u16 indices"
    );
    spot_check(&rows);
    let text = render(&rows, &source);

    if check {
        let scratch = manifest_dir
            .join("target")
            .join(format!("{DIALECT}.check.rs"));
        fs::create_dir_all(scratch.parent().expect("scratch has a parent"))
            .expect("cannot create target/");
        fs::write(&scratch, text).expect("cannot write scratch file");
        rustfmt(&scratch);
        let new = fs::read(&scratch).expect("cannot read scratch file");
        let old = fs::read(&out).unwrap_or_default();
        if new == old {
            println!("{} is up to date ({} messages)", out.display(), rows.len());
            ExitCode::SUCCESS
        } else {
            eprintln!("{} is out of date; run: {REGEN_COMMAND}", out.display());
            ExitCode::FAILURE
        }
    } else {
        fs::write(&out, text).unwrap_or_else(|e| panic!("cannot write {}: {e}", out.display()));
        rustfmt(&out);
        println!(
            "wrote {} ({} messages) from {source}",
            out.display(),
            rows.len()
        );
        ExitCode::SUCCESS
    }
}
