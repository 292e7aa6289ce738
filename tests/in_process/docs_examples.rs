//! Every worked example in docs/configuration.md is a valid configuration.

#[test]
fn worked_examples_are_valid() {
    let doc = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/docs/configuration.md"
    ))
    .expect("docs/configuration.md");
    let section = doc
        .split("## Worked examples")
        .nth(1)
        .and_then(|s| s.split("\n## ").next())
        .expect("worked examples section");
    let blocks: Vec<&str> = section.split("```").skip(1).step_by(2).collect();
    assert!(blocks.len() >= 3);
    for block in blocks {
        if let Err(e) = mavtables::config::load(block) {
            panic!("{}", mavtables::config::render_errors("doc", block, &e));
        }
    }
}

#[test]
fn the_documented_endpoints_are_the_ones_understood() {
    let doc = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/docs/configuration.md"
    ))
    .expect("docs/configuration.md");
    let section = doc
        .split("## Endpoints instead of a file")
        .nth(1)
        .and_then(|s| s.split("\n## ").next())
        .expect("endpoints section");
    for (kind, form, example) in mavtables::cli::endpoints::KINDS {
        assert!(
            section.contains(&format!("| `{kind}:{form}` |")),
            "{kind}:{form} is not documented"
        );
        let arg = format!("{kind}:{example}");
        assert!(
            matches!(mavtables::cli::endpoints::parse(&arg), Ok(Some(_))),
            "{arg}"
        );
    }
    // The command line shown first is one the binary accepts.
    let line = section
        .lines()
        .find(|l| l.starts_with("mavtables "))
        .expect("example command line");
    let args: Vec<&str> = line.split_whitespace().skip(1).collect();
    for arg in args {
        assert!(
            matches!(mavtables::cli::endpoints::parse(arg), Ok(Some(_))),
            "{arg}"
        );
    }
}

#[test]
fn the_signing_deployments_are_valid() {
    let doc = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/docs/configuration.md"
    ))
    .expect("docs/configuration.md");
    let section = doc
        .split("### Three deployments")
        .nth(1)
        .and_then(|s| s.split("\n### ").next())
        .expect("signing deployments");
    let blocks: Vec<&str> = section.split("```").skip(1).step_by(2).collect();
    assert_eq!(blocks.len(), 3);
    for block in blocks {
        let loaded = match mavtables::config::load(block) {
            Ok(l) => l,
            Err(e) => panic!("{}", mavtables::config::render_errors("doc", block, &e)),
        };
        let keyed = loaded
            .config
            .interfaces
            .iter()
            .filter(|i| i.signing().is_some());
        assert!(keyed.count() >= 1, "every deployment has a key:\n{block}");
    }
}

/// The `zenoh` examples of docs/configuration.md load in a router built with Zenoh, and
/// are refused, located and with the way to build one, in a router built without.
#[test]
fn the_zenoh_examples_are_valid_or_refused_with_the_way_out() {
    let doc = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/docs/configuration.md"
    ))
    .expect("docs/configuration.md");
    let section = doc
        .split("## `zenoh` blocks")
        .nth(1)
        .and_then(|s| s.split("\n## ").next())
        .expect("zenoh section");
    let example = section.split("```").nth(1).expect("an example");
    let lines: Vec<&str> = example.lines().filter(|l| l.starts_with("zenoh")).collect();
    assert_eq!(lines.len(), 4);
    for line in lines {
        let loaded = mavtables::config::load(line);
        if cfg!(feature = "zenoh") {
            if let Err(e) = loaded {
                panic!("{}", mavtables::config::render_errors("doc", line, &e));
            }
        } else {
            let e = loaded.map(|_| ()).expect_err("no zenoh in this build");
            let text = mavtables::config::render_errors("doc", line, &e);
            assert!(text.contains("doc:1:1"), "{text}");
            assert!(text.contains("built without Zenoh"), "{text}");
            assert!(
                text.contains("cargo build --release --features zenoh"),
                "{text}"
            );
        }
    }
    // The worked fleet: the vehicle's and the ground station's files load whole.
    let fleet = section
        .split("### A fleet, worked through")
        .nth(1)
        .expect("a worked fleet");
    let files: Vec<&str> = (fleet.split("```").skip(1).step_by(2))
        .filter(|b| b.contains("zenoh {"))
        .collect();
    assert_eq!(files.len(), 2);
    for file in files {
        let loaded = mavtables::config::load(file);
        if cfg!(feature = "zenoh") {
            if let Err(e) = loaded {
                panic!("{}", mavtables::config::render_errors("doc", file, &e));
            }
        } else {
            assert!(loaded.is_err(), "no zenoh in this build");
        }
    }
}
