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
