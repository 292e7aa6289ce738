//! `with rate N/UNIT` in the configuration language: `--ast`, the model, the rule text
//! the statistics show, and located errors.

use super::config_text::tree;
use mavtables::config::{self, Rate, RateUnit};

fn first_error(src: &str) -> String {
    let errors = match config::load(src) {
        Ok(_) => panic!("expected an error for {src:?}"),
        Err(e) => e,
    };
    let rendered = config::render_errors("f", src, &errors);
    rendered.lines().next().unwrap_or_default().to_string()
}

#[test]
fn rates_print_in_the_ast_in_the_order_written() {
    assert_eq!(
        tree("chain default {\n    accept with rate 2/s if ATTITUDE;\n}"),
        ":001:  chain default\n:002:  |  accept\n:002:  |  |  rate 2/s\n:002:  |  |  condition\n:002:  |  |  |  packet_type ATTITUDE\n"
    );
    assert_eq!(
        tree("chain default {\n    accept with priority 3\n      with rate 0.5/s;\n}"),
        ":001:  chain default\n:002:  |  accept\n:002:  |  |  priority 3\n:003:  |  |  rate 0.5/s\n"
    );
    assert_eq!(
        tree("chain default { accept with rate 10/min with priority -1; }"),
        ":001:  chain default\n:001:  |  accept\n:001:  |  |  rate 10/min\n:001:  |  |  priority -1\n"
    );
    // --ast checks syntax only: a rate on a reject prints as written.
    assert_eq!(
        tree("chain default { reject with rate 0/h; }"),
        ":001:  chain default\n:001:  |  reject\n:001:  |  |  rate 0/h\n"
    );
}

#[test]
fn the_model_keeps_the_rate_and_the_rule_text_shows_it() {
    let src = "chain default {\n accept with priority 3 with rate 2/s if ATTITUDE to 254.0/8;\n accept with rate 0.25/s;\n call c;\n}\nchain c { accept with rate 10/min if HEARTBEAT; }";
    let config = config::load(src).expect("loads").config;
    let rules = &config.chains[0].rules;
    assert_eq!(
        rules[0].rate,
        Some(Rate {
            thousandths: 2000,
            unit: RateUnit::Second
        })
    );
    assert_eq!(rules[0].priority, Some(3));
    assert_eq!(
        rules[1].rate.map(|r| r.interval()),
        Some(std::time::Duration::from_secs(4))
    );
    assert_eq!(rules[2].rate, None);
    let texts: Vec<String> = config
        .chains
        .iter()
        .flat_map(|c| &c.rules)
        .map(|r| mavtables::stats::rule_text::rule_text(&config, r))
        .collect();
    assert_eq!(
        texts,
        [
            "accept with priority 3 with rate 2/s if ATTITUDE to 254.0/8",
            "accept with rate 0.25/s",
            "call c",
            "accept with rate 10/min if HEARTBEAT",
        ]
    );
}

#[test]
fn located_errors() {
    let cases = [
        (
            "chain default { reject with rate 2/s; }",
            "f:1:29: a rate applies to 'accept' rules only",
        ),
        (
            "chain default { call c with rate 2/s; }\nchain c { accept; }",
            "f:1:29: a rate applies to 'accept' rules only",
        ),
        (
            "chain default { accept with rate 0/s; }",
            "f:1:34: a rate must be above 0",
        ),
        (
            "chain default { accept with rate 2/ms; }",
            "f:1:34: unknown rate unit 'ms' (write /s, /min or /h)",
        ),
        (
            "chain default { accept with rate 0.0001/s; }",
            "f:1:34: invalid rate (0.0001): write a number with at most 3 decimals, e.g. 2 or 0.5",
        ),
        (
            "chain default { accept with rate 2000000/s; }",
            "f:1:34: rate (2000000/s) is outside of the allowed range (1/day - 1000000/s)",
        ),
        (
            "chain default { accept with rate fast; }",
            "f:1:34: expected a rate",
        ),
        (
            "chain default { accept with rate 2; }",
            "f:1:35: expected a rate",
        ),
        (
            "chain default { accept with rate 2/; }",
            "f:1:36: expected a rate unit",
        ),
        (
            "chain default { accept with rate 2/s with rate 3/s; }",
            "f:1:43: a rule takes one rate",
        ),
        (
            "chain default { accept with priority 1 with priority 2; }",
            "f:1:45: a rule takes one priority",
        ),
        (
            "chain default { accept with speed 2/s; }",
            "f:1:29: 'with' keyword must be followed by the 'priority' keyword",
        ),
    ];
    for (src, want) in cases {
        assert_eq!(first_error(src), want, "{src}");
    }
}
