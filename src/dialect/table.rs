//! [`Dialect`]: the messages a router knows — the built-in `ardupilotmega` table plus
//! those loaded from `dialect` files at run time — and the look-ups the parser, the
//! filter and the tools make in it.
//!
//! Built-in ids are looked up first, exactly as before (a flat table below id 512), so
//! loading a dialect costs them nothing; only an id the built-in table lacks goes on to
//! the loaded messages (a binary search, skipped when none are loaded). Loaded messages
//! never shadow built-in ones: the loader refuses a conflicting definition and drops an
//! identical one.
//!
//! A `Dialect` is two `'static` slices, so it is `Copy` and frames keep handing out
//! `&'static MessageInfo`. Loaded tables live as long as the process: each distinct
//! content is kept once ([`super::load`] interns them), so reloading an unchanged
//! dialect allocates nothing new.

use super::{MessageInfo, by_id as builtin_by_id, by_name as builtin_by_name, messages};

/// The message id the filter sees for a frame whose id no loaded dialect knows (with
/// `unknown_messages accept;`): one past the 24-bit id space, so it is no real id.
pub const UNKNOWN_ID: u32 = 1 << 24;

/// The name rules use for frames of unknown ids: `accept if UNKNOWN;`.
pub const UNKNOWN_NAME: &str = "UNKNOWN";

/// What a frame of an unknown id is checked and described with: no fields, no target
/// (broadcast), any length, no CRC_EXTRA (its checksum cannot be checked).
pub static UNKNOWN_MESSAGE: MessageInfo = MessageInfo {
    id: UNKNOWN_ID,
    name: UNKNOWN_NAME,
    crc_extra: 0,
    min_len: 0,
    max_len: 255,
    target_system_offset: None,
    target_component_offset: None,
    fields: &[],
};

/// The id of `SETUP_SIGNING`, which carries a signing key in the clear: only a rule
/// naming it forwards it.
pub const SETUP_SIGNING_ID: u32 = 256;

/// The built-in messages and those loaded at run time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dialect {
    /// Loaded messages whose ids the built-in table lacks, sorted by id.
    extra: &'static [MessageInfo],
    /// Indices into `extra`, sorted by name.
    by_name: &'static [(&'static str, u32)],
}

/// The built-in `ardupilotmega` table alone.
pub static BUILTIN: Dialect = Dialect {
    extra: &[],
    by_name: &[],
};

impl Default for Dialect {
    fn default() -> Self {
        BUILTIN
    }
}

impl Dialect {
    /// The built-in table plus `extra` (sorted by id, none built-in) and its name index.
    pub(super) fn with_extra(
        extra: &'static [MessageInfo],
        by_name: &'static [(&'static str, u32)],
    ) -> Dialect {
        Dialect { extra, by_name }
    }

    /// The built-in table alone.
    pub fn builtin() -> Dialect {
        BUILTIN
    }

    /// True when nothing was loaded beyond the built-in table.
    pub fn is_builtin(&self) -> bool {
        self.extra.is_empty()
    }

    /// Look a message up by id; `None` for ids no loaded dialect defines.
    #[inline]
    pub fn by_id(&self, id: u32) -> Option<&'static MessageInfo> {
        match builtin_by_id(id) {
            Some(info) => Some(info),
            None => self.loaded_by_id(id),
        }
    }

    /// The loaded message of `id` (out of line: only ids the built-in table lacks).
    #[inline(never)]
    fn loaded_by_id(&self, id: u32) -> Option<&'static MessageInfo> {
        let extra = self.extra;
        extra
            .binary_search_by_key(&id, |m| m.id)
            .ok()
            .and_then(|i| extra.get(i))
    }

    /// Look a message up by its exact (upper-case) name.
    pub fn by_name(&self, name: &str) -> Option<&'static MessageInfo> {
        if let Some(info) = builtin_by_name(name) {
            return Some(info);
        }
        let extra = self.extra;
        self.by_name
            .binary_search_by(|(n, _)| (*n).cmp(name))
            .ok()
            .and_then(|i| self.by_name.get(i))
            .and_then(|&(_, at)| extra.get(at as usize))
    }

    /// The messages loaded beyond the built-in table, sorted by id.
    pub fn loaded(&self) -> &'static [MessageInfo] {
        self.extra
    }

    /// Every message name: the built-in ones, then the loaded ones (for suggestions).
    pub fn names(&self) -> impl Iterator<Item = &'static str> + '_ {
        messages().iter().chain(self.extra.iter()).map(|m| m.name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_builtin_dialect_agrees_with_the_builtin_table() {
        let d = Dialect::builtin();
        for m in messages() {
            assert_eq!(d.by_id(m.id), Some(m));
            assert_eq!(d.by_name(m.name), Some(m));
        }
        assert_eq!(d.by_id(60_123), None);
        assert_eq!(d.by_id(UNKNOWN_ID), None);
        assert_eq!(d.by_name(UNKNOWN_NAME), None);
        assert_eq!(
            d.by_name("SETUP_SIGNING").map(|m| m.id),
            Some(SETUP_SIGNING_ID)
        );
    }
}
