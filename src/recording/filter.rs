//! Which received frames are recorded: the `only if …;` statements of the `record`
//! block, any of which may match (none written: every frame).

use crate::condition::Condition;
use crate::wire::Frame;

/// The conditions a frame must meet (any one of them) to be recorded.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RecordFilter {
    only: Vec<Condition>,
}

impl RecordFilter {
    /// A filter passing frames that meet any of `only`; every frame when it is empty.
    pub fn new(only: Vec<Condition>) -> Self {
        RecordFilter { only }
    }

    /// Whether `frame`, which arrived signed (its signature accepted) or not, is
    /// recorded. A condition's `to` part matches the frame's target address; a frame
    /// without target fields never matches a `to`.
    #[inline]
    pub fn matches(&self, frame: &Frame<'_>, signed: bool) -> bool {
        if self.only.is_empty() {
            return true;
        }
        // The filter's id: `UNKNOWN` matches every frame of an unknown id.
        let (id, source) = (frame.info().id, frame.source());
        self.only.iter().any(|c| {
            c.signed.is_none_or(|s| s == signed)
                && c.message_id.is_none_or(|m| m == id)
                && c.source.is_none_or(|s| s.contains(source))
                && c.dest
                    .is_none_or(|d| frame.target().is_some_and(|t| d.contains(t)))
        })
    }
}
