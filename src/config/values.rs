//! Checks shared by the statement checkers ([`semantics`](super::semantics) and the
//! blocks it hands over: [`sockets`](super::sockets), [`stats_block`](super::stats_block),
//! [`recording`](super::recording)): a number within its range and an interface's
//! signing settings. A leaf: it imports none of them.

use super::Span;
use super::ast::{Ast, YesNo};
use super::diagnostic::Diagnostic;
use super::model::InterfaceSigning;

/// The signing settings of one interface block from its `signing_key` (the last one
/// written) and `allow_unsigned` statements (the last one counts); `allow_unsigned`
/// without a key is an error at the first of them.
pub(super) fn interface_signing(
    ast: &Ast<'_>,
    key_file: Option<Span>,
    allow_unsigned: &[YesNo],
) -> Result<Option<InterfaceSigning>, Diagnostic> {
    match (key_file, allow_unsigned.first()) {
        (Some(path), _) => Ok(Some(InterfaceSigning {
            key_file: ast.text(path).to_string(),
            allow_unsigned: allow_unsigned.last().is_some_and(|v| v.yes),
        })),
        (None, None) => Ok(None),
        (None, Some(first)) => Err(Diagnostic::new(
            first.keyword,
            "'allow_unsigned' needs a 'signing_key' in the same block",
        )
        .with_note(
            "only a block with a signing key checks signatures; add 'signing_key PATH;' or leave out 'allow_unsigned'",
        )),
    }
}

/// True if `word` is written as a number of bytes: digits, then at most one of `K`,
/// `M`, `G`, `T` (its value may still be out of range: [`byte_count`] says).
pub(super) fn looks_like_bytes(word: &str) -> bool {
    let digits = word.strip_suffix(['K', 'M', 'G', 'T']).unwrap_or(word);
    !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())
}

/// A number of bytes as written: decimal digits, optionally followed by `K`, `M`, `G` or
/// `T` for 1024, 1024², 1024³ or 1024⁴ bytes (as systemd reads sizes); `None` for
/// anything else or a value beyond `u64`.
pub(super) fn byte_count(text: &str) -> Option<u64> {
    let (digits, scale) = match text.as_bytes().last()? {
        b'K' => (&text[..text.len() - 1], 1u64 << 10),
        b'M' => (&text[..text.len() - 1], 1 << 20),
        b'G' => (&text[..text.len() - 1], 1 << 30),
        b'T' => (&text[..text.len() - 1], 1 << 40),
        _ => (text, 1),
    };
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse::<u64>().ok()?.checked_mul(scale)
}

/// `text` as a number of bytes ([`byte_count`]) within `min..=max`, or the error text
/// naming `what`.
pub(super) fn ranged_bytes(text: &str, min: u64, max: u64, what: &str) -> Result<u64, String> {
    match byte_count(text) {
        Some(v) if (min..=max).contains(&v) => Ok(v),
        _ => Err(format!(
            "{what} ({text}) is outside of the allowed range ({min} - {max})"
        )),
    }
}

/// `text` as a decimal number within `min..=max`, or the error text naming `what`.
pub(super) fn ranged(text: &str, min: u64, max: u64, what: &str) -> Result<u64, String> {
    match text.parse::<u64>() {
        Ok(v) if (min..=max).contains(&v) => Ok(v),
        _ => Err(format!(
            "{what} ({text}) is outside of the allowed range ({min} - {max})"
        )),
    }
}

/// `text` as a MAVLink system or component id (1 to 255), or the error text naming
/// `what`.
pub(super) fn mavlink_id(text: &str, what: &str) -> Result<u8, String> {
    ranged(text, 1, 255, what).map(|n| u8::try_from(n).unwrap_or(u8::MAX))
}
