//! Capture tools behind `mavtables inspect` and `mavtables replay`.

pub mod inspect;
pub mod replay;
pub mod utc;
