//! The subcommands `mavtables inspect` and `mavtables replay`: what they do with a
//! capture. Their command lines are read in [`crate::cli`].

pub mod inspect;
pub mod replay;
