//! MAVLink 2 signing at the router's edge: the keys interfaces are given ([`key`]), the
//! check of signed frames that arrive and the replay protection of their timestamps
//! ([`verify`], [`streams`]), the signatures the router adds to frames it sends ([`sign`]),
//! the router's own signing clock ([`clock`]) and the saved stream table that outlives a
//! restart ([`state`]). All of it is sans-IO: time comes in as arguments, state goes out
//! as bytes for the I/O layer to write.

pub mod key;

pub use key::{KeyError, SigningKey};
