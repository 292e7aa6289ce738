//! Dialects loaded at run time (`dialect PATH;`), the `unknown_messages` policy and the
//! `SETUP_SIGNING` guard: CRC_EXTRA and lengths against pymavlink's generator, located
//! errors, `--ast`, the parser, the filter and a reload through the routing core.

use crate::common;
use common::router::Scratch;

use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use mavtables::address::Address;
use mavtables::config::{self, Config, parse, print_tree};
use mavtables::dialect::{Loader, SETUP_SIGNING_ID, UNKNOWN_ID, layout, load_files, xml};
use mavtables::filter::{Filter, Verdict};
use mavtables::routing::{Engine, InterfaceId, RouterOptions, Timestamp};
use mavtables::wire::crc::frame_checksum;
use mavtables::wire::{Checks, Parser};

fn dialects() -> PathBuf {
    common::data("dialects")
}

/// Every message of `file` and its includes as we lay it out: `id name crc min max`.
fn our_facts(file: &Path, seen: &mut Vec<PathBuf>, out: &mut Vec<(u32, String)>) {
    if seen.contains(&file.to_path_buf()) {
        return;
    }
    seen.push(file.to_path_buf());
    let text = std::fs::read_to_string(file).expect("xml");
    let parsed = xml::parse(&text).expect("parses");
    let dir = file.parent().expect("dir");
    for inc in &parsed.includes {
        our_facts(&dir.join(&inc.path), seen, out);
    }
    for m in &parsed.messages {
        let l = layout::lay_out(m).expect("lays out");
        out.push((
            l.id,
            format!(
                "{} {} {} {} {}",
                l.id, l.name, l.crc_extra, l.min_len, l.max_len
            ),
        ));
    }
}

#[track_caller]
fn cross_check(file: &str) -> usize {
    let path = dialects().join(file);
    let mut ours = Vec::new();
    our_facts(&path, &mut Vec::new(), &mut ours);
    ours.sort();
    ours.dedup_by_key(|(id, _)| *id);
    let ours: Vec<String> = ours.into_iter().map(|(_, l)| l).collect();
    let path_text = path.to_str().expect("utf-8 path");
    let theirs = common::run_py("dialect_facts.py", &[path_text], "");
    let theirs: Vec<&str> = theirs.lines().collect();
    assert_eq!(ours.len(), theirs.len(), "message count of {file}");
    for (a, b) in ours.iter().zip(&theirs) {
        assert_eq!(a, b, "{file}: ours vs pymavlink mavgen");
    }
    ours.len()
}

#[test]
fn crc_extra_and_lengths_agree_with_pymavlink_on_the_test_dialect() {
    // payload.xml has extensions, arrays, a string and enums, and includes common.xml.
    let n = cross_check("payload.xml");
    assert!(n > 200, "{n} messages");
}

#[test]
fn crc_extra_and_lengths_agree_with_pymavlink_on_common_xml() {
    let n = cross_check("common.xml");
    assert!(n > 200, "{n} messages");
}

/// A v2 frame of `id` with `payload`, checksummed with `crc_extra`.
fn v2(id: u32, source: (u8, u8), payload: &[u8], crc_extra: u8) -> Vec<u8> {
    let mut f = vec![0xFD, payload.len() as u8, 0, 0, 7, source.0, source.1];
    f.extend_from_slice(&id.to_le_bytes()[..3]);
    f.extend_from_slice(payload);
    let crc = frame_checksum(&f[1..], crc_extra);
    f.extend_from_slice(&crc.to_le_bytes());
    f
}

fn payload_config(extra: &str) -> Config {
    let src = format!("dialect payload.xml;\n{extra}");
    match config::load_in(&src, &dialects()) {
        Ok(l) => l.config,
        Err(e) => panic!("{}", config::render_errors("t", &src, &e)),
    }
}

#[test]
fn a_custom_message_is_crc_checked_routed_by_target_and_named_in_rules() {
    let config = payload_config("chain default { accept if MY_PAYLOAD_STATUS to 1.0/8; }");
    let status = config.dialect.by_name("MY_PAYLOAD_STATUS").expect("loaded");
    assert_eq!(
        (status.id, status.min_len, status.max_len),
        (60_123, 37, 47)
    );
    assert_eq!(config.chains[0].rules[0].condition.message_id, Some(60_123));
    // Wire order: the u32 first, then the float array, u16, then the bytes.
    let order: Vec<&str> = status.fields.iter().map(|f| f.name).collect();
    assert_eq!(
        order,
        [
            "samples",
            "temperature",
            "errors",
            "target_system",
            "target_component",
            "state",
            "label",
            "uptime_us",
            "rssi"
        ]
    );
    let mut payload = vec![0u8; 37];
    payload[18] = 1; // target_system
    payload[19] = 5; // target_component
    let good = v2(60_123, (9, 1), &payload, status.crc_extra);
    let bad = v2(60_123, (9, 1), &payload, status.crc_extra ^ 1);
    let mut parser = Parser::new().with_dialect(config.dialect);
    let mut seen = Vec::new();
    parser.feed(&[bad, good.clone()].concat(), |f| {
        seen.push((f.name(), f.target(), f.as_bytes().to_vec()))
    });
    assert_eq!(
        seen,
        [("MY_PAYLOAD_STATUS", Some(Address::new(1, 5)), good)]
    );
    assert_eq!(parser.stats().bad_crc, 1);
    // The built-in parser does not know it.
    let mut builtin = Parser::new();
    builtin.feed(&seen[0].2, |_| panic!("unknown to the built-in table"));
    assert_eq!(builtin.stats().unknown_id, 1);
    // The rule names it.
    let mut filter = Filter::new(&config);
    let src = Address::new(9, 1);
    assert_eq!(
        filter.check(60_123, src, Address::new(1, 5), false),
        Verdict::Accept(0)
    );
    assert_eq!(
        filter.check(60_123, src, Address::new(2, 5), false),
        Verdict::Reject
    );
}

#[test]
fn unknown_ids_are_framed_by_length_only_when_accepted() {
    let frame = v2(60_999, (3, 1), &[1, 2, 3, 4, 5], 0x42);
    let mut reject = Parser::new();
    reject.feed(&frame, |_| panic!("rejected by default"));
    assert_eq!(reject.stats().unknown_id, 1);
    let mut accept = Parser::with_checks(Checks {
        accept_unknown: true,
        ..Checks::ROUTING
    });
    let mut got = Vec::new();
    // Twice, back to back, split across feeds: framed by the length byte.
    let both = [frame.clone(), frame.clone()].concat();
    let (a, b) = both.split_at(9);
    for chunk in [a, b] {
        accept.feed(chunk, |f| {
            got.push((
                f.message_id(),
                f.info().id,
                f.name(),
                f.is_unknown(),
                f.target(),
            ))
        });
    }
    let want = (60_999, UNKNOWN_ID, "UNKNOWN", true, None);
    assert_eq!(got, [want, want]);
}

#[test]
fn unknown_is_a_condition_and_setup_signing_needs_a_rule_naming_it() {
    let config = config::load(
        "unknown_messages accept;\n\
         chain default { reject if UNKNOWN from 7.0/8; accept; }\n",
    )
    .expect("loads")
    .config;
    let mut f = Filter::new(&config);
    let (to, a, b) = (Address::new(0, 0), Address::new(7, 1), Address::new(8, 1));
    assert_eq!(f.check(UNKNOWN_ID, a, to, false), Verdict::Reject);
    assert_eq!(f.check(UNKNOWN_ID, b, to, false), Verdict::Accept(0));
    // `accept;` takes everything but SETUP_SIGNING; so does the default action.
    assert_eq!(f.check(SETUP_SIGNING_ID, b, to, false), Verdict::Reject);
    let all = config::load("default_action accept;")
        .expect("loads")
        .config;
    assert_eq!(
        Filter::new(&all).check(SETUP_SIGNING_ID, b, to, false),
        Verdict::Reject
    );
    // A rule naming it forwards it, even after an `accept` of everything.
    let named =
        config::load("chain default { accept if HEARTBEAT; accept if SETUP_SIGNING from 8.0/8; }")
            .expect("loads")
            .config;
    let mut f = Filter::new(&named);
    assert_eq!(f.check(SETUP_SIGNING_ID, b, to, false), Verdict::Accept(0));
    assert_eq!(f.check(SETUP_SIGNING_ID, a, to, false), Verdict::Reject);
    // Naming UNKNOWN without accepting unknown ids is allowed, with a warning.
    let w = config::load("chain default { accept if UNKNOWN; }").expect("loads");
    assert!(
        w.warnings[0].contains("unknown_messages accept"),
        "{:?}",
        w.warnings
    );
}

#[test]
fn new_statements_print_in_the_ast_style() {
    let src = "dialect payload.xml;\ndialect /etc/mavtables/more.xml;\nunknown_messages accept;\nunknown_messages reject;\nchain default { accept if UNKNOWN to 1.0/8; }\n";
    let ast = parse(src).expect("parses");
    assert_eq!(
        print_tree(&ast),
        ":001:  dialect payload.xml\n\
         :002:  dialect /etc/mavtables/more.xml\n\
         :003:  unknown_messages\n\
         :003:  |  accept\n\
         :004:  unknown_messages\n\
         :004:  |  reject\n\
         :005:  chain default\n\
         :005:  |  accept\n\
         :005:  |  |  condition\n\
         :005:  |  |  |  packet_type UNKNOWN\n\
         :005:  |  |  |  dest 1.0/8\n"
    );
}

/// The first error of `src` loaded in `dir`, rendered for file `f`.
fn error_in(dir: &Path, src: &str) -> String {
    match config::load_in(src, dir) {
        Ok(_) => panic!("expected an error for {src:?}"),
        Err(e) => config::render_errors("f", src, &e),
    }
}

fn write(dir: &Path, name: &str, text: &str) {
    std::fs::write(dir.join(name), text).expect("write");
}

const ONE: &str = r#"<mavlink><messages>
<message id="60200" name="ONE"><field type="uint8_t" name="a">A.</field></message>
</messages></mavlink>
"#;

#[test]
fn dialect_problems_are_located_errors() {
    let scratch = Scratch::new("dialect-errors");
    let dir = scratch.dir.clone();
    write(&dir, "one.xml", ONE);
    let first_line = |src: &str| {
        error_in(&dir, src)
            .lines()
            .next()
            .unwrap_or_default()
            .to_string()
    };
    let d = dir.display();

    // Syntax.
    assert!(
        first_line("dialect ;")
            .starts_with("f:1:9: expected the path of a MAVLink XML dialect file")
    );
    assert!(
        first_line("unknown_messages maybe;").starts_with("f:1:18: expected 'accept' or 'reject'")
    );
    // A missing file, with the directory relative paths are taken from.
    let e = error_in(&dir, "dialect nope.xml;");
    assert!(
        e.starts_with(&format!(
            "f:1:9: cannot load the dialect: {d}/nope.xml: does not exist"
        )),
        "{e}"
    );
    assert!(
        e.contains(&format!(
            "relative path is taken from the configuration file's directory ({d})"
        )),
        "{e}"
    );
    // Not a regular file; too large.
    let e = first_line(&format!("dialect {d};"));
    assert!(e.contains("is a directory, not a regular file"), "{e}");
    let big = std::fs::File::create(dir.join("big.xml")).expect("create");
    big.set_len(5 << 20).expect("sparse");
    let e = first_line("dialect big.xml;");
    assert!(e.contains("is larger than the limit of 4 MiB"), "{e}");
    // Malformed XML, at its line.
    write(
        &dir,
        "bad.xml",
        "<mavlink>\n<messages>\n<message id=\"1\" name=\"X\">\n</messages></mavlink>\n",
    );
    let e = first_line("\n dialect bad.xml;");
    assert!(
        e.starts_with(&format!(
            "f:2:10: cannot load the dialect: {d}/bad.xml:4: malformed XML"
        )),
        "{e}"
    );
    // A missing include, at the include's line.
    write(
        &dir,
        "inc.xml",
        "<mavlink>\n  <include>gone.xml</include>\n</mavlink>\n",
    );
    let e = first_line("dialect inc.xml;");
    assert!(
        e.contains(&format!(
            "{d}/inc.xml:2: included file {d}/gone.xml does not exist"
        )),
        "{e}"
    );
    // An id the built-in table has with another definition.
    write(
        &dir,
        "clash.xml",
        "<mavlink><messages>\n<message id=\"0\" name=\"NOT_HEARTBEAT\"><field type=\"uint8_t\" name=\"a\">A</field></message>\n</messages></mavlink>",
    );
    let e = first_line("dialect clash.xml;");
    assert!(e.contains("clash.xml:2: message id 0 is HEARTBEAT (CRC_EXTRA 50) in the built-in 'ardupilotmega' dialect; here it is NOT_HEARTBEAT"), "{e}");
    // A name used twice (across two dialect statements), located at the second.
    write(&dir, "two.xml", &ONE.replace("60200", "60201"));
    let e = first_line("dialect one.xml;\ndialect two.xml;");
    assert!(e.starts_with("f:2:9: cannot load the dialect:"), "{e}");
    assert!(e.contains("message name ONE is already id 60200 at"), "{e}");
    // An id defined twice differently.
    write(
        &dir,
        "three.xml",
        &ONE.replace("name=\"ONE\"", "name=\"THREE\""),
    );
    let e = first_line("dialect one.xml;\ndialect three.xml;");
    assert!(e.contains("message id 60200 is already ONE"), "{e}");
    // The reserved name, an unknown type, a payload too long.
    write(
        &dir,
        "unk.xml",
        &ONE.replace("name=\"ONE\"", "name=\"UNKNOWN\""),
    );
    assert!(first_line("dialect unk.xml;").contains("the message name UNKNOWN is reserved"));
    write(&dir, "type.xml", &ONE.replace("uint8_t", "uint7_t"));
    assert!(first_line("dialect type.xml;").contains("unknown type 'uint7_t'"));
    write(&dir, "long.xml", &ONE.replace("uint8_t", "uint64_t[40]"));
    assert!(first_line("dialect long.xml;").contains("payload of 320 bytes"));
    // Rules naming a message of a file that failed are not reported twice over.
}

#[test]
fn a_dialect_is_read_relative_to_the_configuration_file() {
    let scratch = Scratch::new("dialect-relative");
    let dir = scratch.dir.clone();
    write(&dir, "one.xml", ONE);
    let conf = dir.join("router.conf");
    std::fs::write(
        &conf,
        "dialect one.xml;\nchain default { accept if ONE; }\n",
    )
    .expect("conf");
    let from = config::read_file(conf.to_str().expect("utf-8")).expect("loads");
    assert_eq!(
        from.config.dialect.by_name("ONE").map(|m| m.id),
        Some(60_200)
    );
    assert_eq!(from.config.dialect_files, [dir.join("one.xml")]);
}

#[test]
fn loading_the_same_dialect_twice_gives_the_same_tables() {
    let a = load_files(&[dialects().join("payload.xml")]).expect("loads");
    let mut loader = Loader::new();
    loader.add(&dialects().join("payload.xml")).expect("loads");
    // common.xml again: read once, adds nothing.
    loader.add(&dialects().join("common.xml")).expect("loads");
    let b = loader.finish();
    assert_eq!(a, b);
    assert!(std::ptr::eq(a.loaded(), b.loaded()));
}

fn peer(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

/// What the core sends now on `iface`: (peer port, bytes).
fn sent(e: &mut Engine, iface: InterfaceId, t: Timestamp) -> Vec<(u16, Vec<u8>)> {
    let mut queue = std::collections::VecDeque::new();
    e.poll_transmit(iface, t, 64, &mut queue);
    queue
        .into_iter()
        .map(|x| {
            e.on_sent(&x);
            (x.to.map_or(0, |a| a.port()), x.packet.to_vec())
        })
        .collect()
}

/// Unknown ids dropped and accepted, per link.
fn unknown(e: &Engine) -> Vec<(u64, u64)> {
    e.router()
        .links()
        .map(|l| (l.counters().unknown_id, l.counters().unknown_accepted))
        .collect()
}

#[test]
fn a_reload_picks_up_a_changed_dialect_and_policy() {
    let t = Timestamp::ZERO;
    let base = "udp { port 14000; }\ndefault_action accept;\n";
    let plain = config::load(base).expect("loads").config;
    let mut e = Engine::new(&plain, RouterOptions::default());
    e.configure(&plain, &[], t);
    let iface = InterfaceId(0);
    let heartbeat = |sys: u8| v2(0, (sys, 1), &[0; 9], 50);
    let with = payload_config(base);
    let status = with.dialect.by_name("MY_PAYLOAD_STATUS").expect("loaded");
    let custom = v2(60_123, (2, 1), &[0; 37], status.crc_extra);
    let other = v2(60_999, (2, 1), &[9; 4], 0);
    // Two peers, so frames from peer 2 have somewhere to go (peer 1).
    e.handle_datagram(iface, peer(1), &heartbeat(1), t);
    e.handle_datagram(iface, peer(2), &heartbeat(2), t);
    assert_eq!(sent(&mut e, iface, t), [(1, heartbeat(2))]);
    e.handle_datagram(iface, peer(2), &custom, t);
    e.handle_datagram(iface, peer(2), &other, t);
    assert_eq!(sent(&mut e, iface, t), []);
    assert_eq!(unknown(&e), [(0, 0), (2, 0)]);
    // Reload with the dialect: the custom message now passes, the other id still not.
    let done = e.configure(&with, &[], t);
    assert!(
        done.dialect_changed && done.to_string().contains("dialect changed"),
        "{done}"
    );
    e.handle_datagram(iface, peer(2), &custom, t);
    e.handle_datagram(iface, peer(2), &other, t);
    assert_eq!(sent(&mut e, iface, t), [(1, custom.clone())]);
    assert_eq!(unknown(&e), [(0, 0), (3, 0)]);
    // With unknown ids accepted, the other one too: a broadcast, byte for byte.
    let open = payload_config(&format!("{base}unknown_messages accept;\n"));
    assert!(e.configure(&open, &[], t).dialect_changed);
    e.handle_datagram(iface, peer(2), &other, t);
    assert_eq!(sent(&mut e, iface, t), [(1, other.clone())]);
    assert_eq!(unknown(&e), [(0, 0), (3, 1)]);
    // An unchanged reload changes nothing.
    assert!(!e.configure(&open, &[], t).dialect_changed);
}

/// The fenced block after `marker` in docs/configuration.md.
fn doc_block(doc: &str, marker: &str, nth: usize) -> String {
    let section = doc.split(marker).nth(1).expect("section");
    let block = section.split("```").nth(1 + 2 * nth).expect("block");
    block.strip_prefix("xml").unwrap_or(block).to_string()
}

#[test]
fn the_documented_custom_payload_example_loads_and_checks_its_frames() {
    let doc = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/docs/configuration.md"
    ))
    .expect("docs");
    let marker = "### A custom payload, worked through";
    let scratch = Scratch::new("dialect-doc");
    let dir = scratch.dir.clone();
    write(&dir, "payload.xml", &doc_block(&doc, marker, 0));
    for f in ["common.xml", "standard.xml", "minimal.xml"] {
        std::fs::copy(dialects().join(f), dir.join(f)).expect("copy");
    }
    let conf = dir.join("mavtables.conf");
    std::fs::write(&conf, doc_block(&doc, marker, 1)).expect("conf");
    let from = config::read_file(conf.to_str().expect("utf-8")).unwrap_or_else(|e| panic!("{e}"));
    let m = from
        .config
        .dialect
        .by_name("MY_PAYLOAD_STATUS")
        .expect("loaded");
    assert_eq!((m.id, m.min_len, m.max_len), (60_123, 37, 47));
    // The same message as the test dialect's (same fields): the same CRC_EXTRA.
    let test = payload_config("").dialect;
    assert_eq!(test.by_id(60_123).map(|t| t.crc_extra), Some(m.crc_extra));
    // And the `unknown_messages` example is a valid configuration.
    let unknown = doc_block(&doc, "## `unknown_messages`", 1);
    config::load(&unknown)
        .unwrap_or_else(|e| panic!("{}", config::render_errors("doc", &unknown, &e)));
}

#[test]
fn damaged_xml_is_an_error_with_a_line_never_a_panic() {
    let text = std::fs::read_to_string(dialects().join("payload.xml")).expect("xml");
    let bytes = text.as_bytes();
    let lines = text.lines().count() + 1;
    let mut tried = 0;
    // Every cut, and a byte changed at many places, in several ways.
    let mut inputs: Vec<Vec<u8>> = (0..bytes.len())
        .step_by(7)
        .map(|n| bytes[..n].to_vec())
        .collect();
    for at in (0..bytes.len()).step_by(13) {
        for b in [b'<', b'>', b'"', b'/', b'9', 0, 0xff, b'&'] {
            let mut v = bytes.to_vec();
            v[at] = b;
            inputs.push(v);
        }
    }
    for input in inputs {
        let text = String::from_utf8_lossy(&input);
        match xml::parse(&text) {
            Ok(file) => {
                for m in &file.messages {
                    if let Ok(l) = layout::lay_out(m) {
                        assert!(l.min_len <= l.max_len);
                    }
                }
            }
            Err(e) => assert!((1..=lines).contains(&e.line), "{e}"),
        }
        tried += 1;
    }
    assert!(tried > 1000);
}

/// `inspect --dialect` names and decodes a custom message and `replay --dialect` sends
/// it; without the option both know only the built-in messages (the custom frame is an
/// unknown id to `inspect`, and `replay` leaves it out). The real binary, a raw capture
/// and a UDP socket on 127.0.0.1.
#[test]
fn inspect_and_replay_read_custom_messages_with_dialect() {
    let scratch = Scratch::new("dialect-tools");
    let dir = scratch.dir.clone();
    let config = payload_config("");
    let status = config.dialect.by_name("MY_PAYLOAD_STATUS").expect("loaded");
    let mut payload = vec![0u8; 37];
    payload[..4].copy_from_slice(&4242u32.to_le_bytes()); // samples
    let custom = v2(60_123, (9, 1), &payload, status.crc_extra);
    let heartbeat = {
        let hb = config.dialect.by_name("HEARTBEAT").expect("built in");
        v2(0, (9, 1), &[0, 0, 0, 0, 18, 8, 0, 0, 3], hb.crc_extra)
    };
    let capture = dir.join("capture.raw");
    std::fs::write(&capture, [heartbeat.clone(), custom.clone()].concat()).expect("write");
    let xml = dialects().join("payload.xml");
    let bin = common::router::BIN;
    let run = |args: &[&std::ffi::OsStr]| {
        let out = std::process::Command::new(bin)
            .args(args)
            .output()
            .expect("run mavtables");
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let os = |s: &str| std::ffi::OsString::from(s);
    let json = run(&[
        &os("inspect"),
        &os("--json"),
        &os("--dialect"),
        xml.as_os_str(),
        capture.as_os_str(),
    ]);
    assert!(
        json.contains("\"name\":\"MY_PAYLOAD_STATUS\"") && json.contains("\"samples\":4242"),
        "{json}"
    );
    let plain = run(&[&os("inspect"), &os("--check"), capture.as_os_str()]);
    assert!(plain.contains("invalid"), "without --dialect: {plain}");

    let sink = std::net::UdpSocket::bind("127.0.0.1:0").expect("bind");
    sink.set_read_timeout(Some(std::time::Duration::from_secs(5)))
        .expect("timeout");
    let to = format!("udp:{}", sink.local_addr().expect("addr"));
    let received = |with_dialect: bool| {
        let mut args = vec![
            os("replay"),
            capture.clone().into_os_string(),
            os("--to"),
            os(&to),
        ];
        if with_dialect {
            args.extend([os("--dialect"), xml.clone().into_os_string()]);
        }
        let refs: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_os_str()).collect();
        run(&refs);
        let mut got = Vec::new();
        let mut buf = [0u8; 512];
        // The replay has finished: what it sent is queued on the socket already.
        sink.set_nonblocking(true).expect("nonblocking");
        while let Ok(n) = sink.recv(&mut buf) {
            got.push(buf[..n].to_vec());
        }
        got
    };
    assert_eq!(received(false), std::slice::from_ref(&heartbeat));
    assert_eq!(received(true), [heartbeat, custom]);
}
