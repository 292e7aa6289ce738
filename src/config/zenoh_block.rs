//! The meaning of a `zenoh` block: its mode, endpoints, key prefix and subscriptions
//! checked, defaults filled in. A router built without the `zenoh` feature refuses the
//! block, saying how to build one that has it.

use super::Span;
use super::ast::{Ast, YesNo, ZenohSetting};
use super::diagnostic::{Diagnostic, Position};
use super::model::{ZenohInterface, ZenohMode, ZenohReceive};
use super::net::{self, TextError};
use super::values::interface_signing;

/// The Zenoh transports this router is built with.
const TRANSPORTS: &[&str] = &["tcp"];

/// Checks the statements of one `zenoh` block; `None` after reporting its errors.
pub(crate) fn check(
    ast: &Ast<'_>,
    keyword: Span,
    settings: &[ZenohSetting],
    errors: &mut Vec<Diagnostic>,
) -> Option<ZenohInterface> {
    // Checked in full either way (so the fuzzer reaches these checks in any build), but
    // said first.
    if !cfg!(feature = "zenoh") {
        errors.push(
            Diagnostic::new(keyword, "this router was built without Zenoh").with_note(
                "build one with the Zenoh interface: cargo build --release --features zenoh",
            ),
        );
    }
    let before = errors.len();
    let mut mode: Option<(ZenohMode, Span)> = None;
    let mut prefix: Option<(String, Span)> = None;
    let mut receive: Option<(ZenohReceive, Span)> = None;
    let (mut connect, mut listen) = (Vec::new(), Vec::new());
    let mut key_file = None;
    let mut allow_unsigned: Vec<YesNo> = Vec::new();
    // A statement that may be written once: a second one is an error naming the first.
    let once = |first: Option<Span>, at: Span, name: &str, errors: &mut Vec<Diagnostic>| {
        if let Some(first) = first {
            let line = Position::of(ast.src, first.start).line;
            errors.push(
                Diagnostic::new(at, format!("only one '{name}' statement is allowed"))
                    .with_note(format!("the first one is on line {line}")),
            );
        }
    };
    for s in settings {
        match *s {
            ZenohSetting::Mode(v) => {
                once(mode.map(|m| m.1), v, "mode", errors);
                match ast.text(v) {
                    "client" => mode = Some((ZenohMode::Client, v)),
                    "peer" => mode = Some((ZenohMode::Peer, v)),
                    _ => errors.push(
                        Diagnostic::new(v, "expected 'client' or 'peer'").with_note(
                            "client: through a Zenoh router it connects to; peer: directly to other peers",
                        ),
                    ),
                }
            }
            ZenohSetting::Receive(v) => {
                once(receive.map(|r| r.1), v, "receive", errors);
                match ast.text(v) {
                    "addressed" => receive = Some((ZenohReceive::Addressed, v)),
                    "all" => receive = Some((ZenohReceive::All, v)),
                    _ => errors.push(
                        Diagnostic::new(v, "expected 'addressed' or 'all'").with_note(
                            "addressed: broadcasts and frames for the systems behind this router (an edge); all: the whole fleet (a ground station)",
                        ),
                    ),
                }
            }
            ZenohSetting::Prefix(v) => {
                once(prefix.as_ref().map(|p| p.1), v, "prefix", errors);
                match key_prefix(ast.text(v)) {
                    Ok(()) => prefix = Some((ast.text(v).to_string(), v)),
                    Err(e) => errors.push(located(v, e)),
                }
            }
            ZenohSetting::Connect(v) | ZenohSetting::Listen(v) => match endpoint(ast.text(v)) {
                Ok(()) if matches!(s, ZenohSetting::Connect(_)) => {
                    connect.push(ast.text(v).to_string());
                }
                Ok(()) => listen.push(ast.text(v).to_string()),
                Err(e) => errors.push(located(v, e)),
            },
            ZenohSetting::SigningKey(v) => key_file = Some(v),
            ZenohSetting::AllowUnsigned(v) => allow_unsigned.push(v),
        }
    }
    let signing = interface_signing(ast, key_file, &allow_unsigned).unwrap_or_else(|d| {
        errors.push(d);
        None
    });
    let mode = mode.map_or(ZenohMode::Client, |m| m.0);
    if errors.len() > before {
        return None;
    }
    match mode {
        ZenohMode::Client if connect.is_empty() => errors.push(
            Diagnostic::new(keyword, "a Zenoh client needs a 'connect' statement")
                .with_note("name its Zenoh router, e.g. 'connect tcp/10.0.0.5:7447;', or write 'mode peer;'"),
        ),
        ZenohMode::Peer if connect.is_empty() && listen.is_empty() => errors.push(
            Diagnostic::new(keyword, "a Zenoh peer needs a 'listen' or a 'connect' statement")
                .with_note("peers find each other only through the endpoints written here (no multicast scouting)"),
        ),
        ZenohMode::Client if !listen.is_empty() => errors.push(
            Diagnostic::new(keyword, "a Zenoh client does not listen")
                .with_note("leave out 'listen', or write 'mode peer;'"),
        ),
        _ => {}
    }
    if errors.len() > before || !cfg!(feature = "zenoh") {
        return None;
    }
    Some(ZenohInterface {
        mode,
        connect,
        listen,
        prefix: prefix.map_or_else(|| ZenohInterface::DEFAULT_PREFIX.to_string(), |p| p.0),
        receive: receive.map_or(ZenohReceive::Addressed, |r| r.0),
        signing,
    })
}

/// `e`, a problem in the text at `span`, as a diagnostic pointing into it.
fn located(span: Span, e: TextError) -> Diagnostic {
    let at = Span::new(span.start + e.at.start, span.start + e.at.end);
    let d = Diagnostic::new(at, e.message);
    match e.note {
        Some(note) => d.with_note(note),
        None => d,
    }
}

/// Warnings for `zenoh` blocks (by line, with their prefixes) whose prefixes are the
/// same or one inside the other: on one Zenoh network, each would hear what the other
/// publishes and pass it back, so frames would go round between them. Blocks on
/// separate networks may share a prefix, so this is not an error.
pub(super) fn overlapping(blocks: &[(usize, String)]) -> Vec<String> {
    let inside = |a: &str, b: &str| {
        b.strip_prefix(a)
            .is_some_and(|rest| rest.is_empty() || rest.starts_with('/'))
    };
    let mut said = Vec::new();
    for (i, (line_a, a)) in blocks.iter().enumerate() {
        for (line_b, b) in &blocks[i + 1..] {
            if inside(a, b) || inside(b, a) {
                said.push(format!(
                    "the zenoh blocks on lines {line_a} and {line_b} publish under '{a}' and '{b}', \
                     one within the other: on one Zenoh network each hears what the other \
                     publishes and frames go round between them; give them prefixes apart \
                     unless their networks are separate"
                ));
            }
        }
    }
    said
}

/// A key prefix: chunks separated by `/`, none empty, with no wildcard or reserved
/// character of Zenoh key expressions (`*`, `$`, `?`, `#`).
fn key_prefix(text: &str) -> Result<(), TextError> {
    let mut at = 0;
    for chunk in text.split('/') {
        if chunk.is_empty() {
            return Err(TextError {
                at: at..at + 1.min(text.len() - at),
                message: "a key prefix has no empty chunk (no leading, trailing or double '/')"
                    .into(),
                note: Some("write it like fleet/alpha".into()),
            });
        }
        if let Some(i) = chunk.find(['*', '$', '?', '#']) {
            return Err(TextError {
                at: at + i..at + i + 1,
                message: "a key prefix has no wildcard or reserved character ('*', '$', '?', '#')"
                    .into(),
                note: Some("the prefix is where this router publishes; subscribers may use wildcards, it may not".into()),
            });
        }
        at += chunk.len() + 1;
    }
    Ok(())
}

/// A Zenoh endpoint of a transport this router is built with: `tcp/HOST:PORT` (also
/// the value of the `zenoh-client:` and `zenoh-peer:` command-line endpoints).
pub(crate) fn endpoint(text: &str) -> Result<(), TextError> {
    let Some((transport, address)) = text.split_once('/') else {
        return Err(TextError {
            at: 0..text.len(),
            message: "expected a Zenoh endpoint: TRANSPORT/HOST:PORT".into(),
            note: Some("e.g. tcp/10.0.0.5:7447 or tcp/[fd00::7]:7447".into()),
        });
    };
    if !TRANSPORTS.contains(&transport) {
        return Err(TextError {
            at: 0..transport.len(),
            message: format!("the Zenoh transport '{transport}' is not built into this router"),
            note: Some(format!("use one of: {}", TRANSPORTS.join(", "))),
        });
    }
    let offset = transport.len() + 1;
    let shift = |mut e: TextError| {
        e.at = e.at.start + offset..e.at.end + offset;
        e
    };
    let hp = net::split_host_port(address).map_err(shift)?;
    net::host(&address[hp.host.clone()], hp.bracketed).map_err(|e| {
        let base = hp.host.start;
        shift(TextError {
            at: e.at.start + base..e.at.end + base,
            ..e
        })
    })?;
    net::port(&address[hp.port.clone()], 0).map_err(|e| {
        let base = hp.port.start;
        shift(TextError {
            at: e.at.start + base..e.at.end + base,
            ..e
        })
    })?;
    Ok(())
}

#[cfg(test)]
mod tests {
    #[cfg(feature = "zenoh")]
    use super::super::model::{Interface, ZenohMode, ZenohReceive};

    #[cfg(feature = "zenoh")]
    fn zenoh(src: &str) -> super::ZenohInterface {
        match crate::config::load(src)
            .expect("loads")
            .config
            .interfaces
            .first()
        {
            Some(Interface::Zenoh(z)) => z.clone(),
            other => panic!("a zenoh interface, not {other:?}"),
        }
    }

    #[test]
    #[cfg(feature = "zenoh")]
    fn defaults_and_values() {
        let z = zenoh("zenoh { connect tcp/127.0.0.1:7447; }");
        assert_eq!(z.mode, ZenohMode::Client);
        assert_eq!(z.prefix, "mavtables");
        assert_eq!(z.receive, ZenohReceive::Addressed);
        let z = zenoh(
            "zenoh { mode peer; listen tcp/127.0.0.1:7448; listen tcp/[::1]:7448; \
             connect tcp/gs.example:7447; prefix fleet/alpha; receive all; }",
        );
        assert_eq!(z.mode, ZenohMode::Peer);
        assert_eq!(z.listen, ["tcp/127.0.0.1:7448", "tcp/[::1]:7448"]);
        assert_eq!(z.connect, ["tcp/gs.example:7447"]);
        assert_eq!(
            (z.prefix.as_str(), z.receive),
            ("fleet/alpha", ZenohReceive::All)
        );
    }

    proptest::proptest! {
        /// Whatever the values, a `zenoh` block loads or gets located errors that
        /// render (spans on character boundaries), never a panic.
        #[test]
        fn any_values_load_or_are_located(a in "\\PC{0,20}", b in "[a-z/*:.\\[\\]0-9é]{0,20}") {
            for src in [
                format!("zenoh {{ connect {a}; listen {b}; prefix {b}; mode {a}; }}"),
                format!("zenoh {{ mode peer; connect tcp/{b}; prefix {a}; receive {b}; }}"),
            ] {
                if let Err(errors) = crate::config::load(&src) {
                    for e in &errors {
                        proptest::prop_assert!(e.span.end <= src.len());
                        let _ = e.render("f", &src);
                    }
                }
            }
        }
    }

    #[test]
    fn blocks_whose_prefixes_nest_are_warned_of() {
        let blocks = |p: &[&str]| -> Vec<(usize, String)> {
            p.iter()
                .enumerate()
                .map(|(i, p)| (i + 1, p.to_string()))
                .collect()
        };
        let said = super::overlapping(&blocks(&["fleet", "fleet/all", "fleetx", "other"]));
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(said[0].starts_with(
            "the zenoh blocks on lines 1 and 2 publish under 'fleet' and 'fleet/all'"
        ));
        assert_eq!(super::overlapping(&blocks(&["a/b", "a/b"])).len(), 1);
        assert!(super::overlapping(&blocks(&["a/b", "a/c", "b"])).is_empty());
    }

    /// Each mistake is located (in any build: the checks run either way).
    #[test]
    fn mistakes_are_located() {
        for (src, text) in [
            (
                "zenoh { mode server; connect tcp/1.2.3.4:7447; }",
                "expected 'client' or 'peer'",
            ),
            (
                "zenoh { connect udp/1.2.3.4:7447; }",
                "'udp' is not built into",
            ),
            ("zenoh { connect tcp/1.2.3.4; }", "port"),
            (
                "zenoh { connect tcp/1.2.3.4:7447; prefix fleet/*; }",
                "wildcard",
            ),
            (
                "zenoh { connect tcp/1.2.3.4:7447; prefix /fleet; }",
                "empty chunk",
            ),
            (
                "zenoh { connect tcp/1.2.3.4:7447; receive some; }",
                "'addressed' or 'all'",
            ),
            ("zenoh { }", "needs a 'connect'"),
            ("zenoh { mode peer; }", "needs a 'listen' or a 'connect'"),
            (
                "zenoh { connect tcp/1.2.3.4:7447; listen tcp/1.2.3.4:7448; }",
                "does not listen",
            ),
            (
                "zenoh { connect tcp/1.2.3.4:7447; mode peer; mode peer; }",
                "only one 'mode'",
            ),
            (
                "zenoh { connect tcp/1.2.3.4:7447; allow_unsigned yes; }",
                "needs a 'signing_key'",
            ),
            ("zenoh { port 5; }", "unsupported statement"),
        ] {
            let errors = crate::config::load(src).map(|_| ()).expect_err(src);
            let all: String = errors.iter().map(|d| d.render("f", src)).collect();
            assert!(all.contains(text), "{src}: {all}");
        }
    }
}
