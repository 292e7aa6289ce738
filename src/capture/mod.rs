//! Reading MAVLink captures: ground-station `.tlog` files and classic `.pcap` files.
//! Pure parsers over byte slices; callers read the files.

pub mod pcap;
pub mod tlog;
