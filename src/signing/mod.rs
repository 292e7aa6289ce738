//! MAVLink 2 signing at the router's edge: the keys interfaces are given (`key`), the
//! check of signed frames that arrive and the replay protection of their timestamps
//! ([`verify`], [`streams`]), the signatures the router adds to frames it sends ([`sign`]),
//! the router's own signing clock ([`clock`]), the saved stream table that outlives a
//! restart ([`state`]), and how the routing core holds all of it (`edge`). All of it but
//! `key`, which reads key files (through `crate::files`), is sans-IO: time comes in
//! as arguments, state goes out as text for the I/O layer to write. The bytes of a
//! signature are computed and written by [`crate::wire::signing`].

#[doc(hidden)]
pub mod clock;
pub(crate) mod counters;
pub(crate) mod edge;
pub(crate) mod key;
#[doc(hidden)]
pub mod sign;
#[doc(hidden)]
pub mod state;
#[doc(hidden)]
pub mod streams;
#[doc(hidden)]
pub mod verify;

pub use crate::wire::signing::SigningTime;
pub use counters::SigningCounters;
pub use edge::{Edge, Signing};
pub use key::{KeyError, SigningKey};
pub use verify::{Admission, Refusal};
