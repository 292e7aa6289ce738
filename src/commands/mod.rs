//! The subcommands `mavtables inspect` and `mavtables replay` (what they do with a
//! capture) and `mavtables stats` (a running router's counters). Their command lines are
//! read in [`crate::cli`].

pub mod inspect;
pub mod replay;
pub mod stats;
