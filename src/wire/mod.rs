//! The MAVLink wire format: frame layout, checksums, the streaming frame parser and
//! signature checking. Pure functions over bytes; no I/O.
