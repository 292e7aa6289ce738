//! Sizes in bytes (`link_bytes`, `total_bytes`, `max_file_bytes`, `min_free_bytes`):
//! plain digits or digits with a `K`, `M`, `G` or `T` suffix (binary multiples), printed
//! by `--ast` as written, and located errors for anything else.

use super::config_text::{first_error, tree};
use mavtables::config;

#[test]
fn suffixes_are_binary_multiples_in_every_byte_statement() {
    let c = config::load(
        "queue { link_bytes 256K; total_bytes 16M; }\n\
         record { path /tmp/r/%H.tlog; max_file_bytes 1G; min_free_bytes 2T; }\n\
         flight_log { min_free_bytes 100M; }",
    )
    .expect("loads")
    .config;
    assert_eq!(c.queue.link_bytes, Some(256 * 1024));
    assert_eq!(c.queue.total_bytes, Some(16 * 1024 * 1024));
    let record = c.record.expect("record");
    assert_eq!(record.max_file_bytes, 1 << 30);
    assert_eq!(record.min_free_bytes, 2 << 40);
    assert_eq!(c.flight_log.expect("flight_log").min_free_bytes, 100 << 20);
    // Plain digits keep meaning bytes.
    let c = config::load("flight_log { min_free_bytes 1000; }").expect("loads");
    assert_eq!(
        c.config.flight_log.expect("flight_log").min_free_bytes,
        1000
    );
}

#[test]
fn ast_prints_the_size_as_written() {
    assert_eq!(
        tree("flight_log { min_free_bytes 100M; }"),
        ":001:  flight_log\n:001:  |  min_free_bytes 100M\n"
    );
}

#[test]
fn other_spellings_are_located_errors() {
    for (src, want) in [
        (
            "flight_log { min_free_bytes 100MB; }",
            "f:1:29: expected a valid number of bytes",
        ),
        (
            // The '.' ends the word: the statement should have ended there.
            "flight_log { min_free_bytes 1.5G; }",
            "f:1:30: expected end of statement ';' character",
        ),
        (
            "flight_log { min_free_bytes 100m; }",
            "f:1:29: expected a valid number of bytes",
        ),
        (
            "record { max_file_bytes M; }",
            "f:1:25: expected a valid number of bytes",
        ),
        (
            "queue { link_bytes 2T; }",
            "f:1:20: link_bytes (2T) is outside of the allowed range (312 - 1099511627776)",
        ),
        (
            "record { path /tmp/r/%H.tlog; max_file_bytes 99999999999999999T; }",
            "f:1:46: max_file_bytes (99999999999999999T) is outside of the allowed range (1024 - 18446744073709551615)",
        ),
    ] {
        assert_eq!(first_error(src), want, "{src}");
    }
}
