//! What the core tells the event loop ([`Engine::poll_event`]): lines for the operator,
//! links that came and went, and streams to open or drop.
//!
//! [`Engine::poll_event`]: super::Engine::poll_event

use super::event::Event;
use super::interface::InterfaceId;
use super::link::LinkId;
use crate::signing::state::SavedState;

/// Something the core tells the event loop: lines for the operator, links that came and
/// went, and streams to open.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Notice {
    /// A routing log line, printed at its level (1–3).
    Log(Event),
    /// A datagram peer sent its first valid frame and is now a link.
    LinkAdded {
        /// The new link.
        id: LinkId,
        /// Its name (`a.b.c.d:port`).
        name: String,
    },
    /// A datagram link was removed: its addresses expired.
    LinkRemoved {
        /// The link.
        id: LinkId,
        /// Its name.
        name: String,
    },
    /// A warning for standard error.
    Warning(String),
    /// An error for standard error.
    Error(String),
    /// A message id outside the dialect was seen for the first time.
    UnknownId(u32),
    /// The interface (a stream, or a datagram client) should be opened now; answer with
    /// [`Engine::stream_opened`](super::Engine::stream_opened) or
    /// [`Engine::stream_open_failed`](super::Engine::stream_open_failed).
    Open(InterfaceId),
    /// The accepted connection was removed (it closed): drop its driver.
    Closed(InterfaceId),
    /// A statistics snapshot is due (once a second, when the configuration has a `stats`
    /// block): take [`Engine::stats`](super::Engine::stats) and publish it.
    PublishStats,
    /// The signing state changed since it was last saved (said at most once a second):
    /// write it to the state file.
    SaveSigningState(Box<SavedState>),
}
