//! The packet filter: chains of `accept` / `reject` / `call` / `goto` rules evaluated for
//! every (packet, destination address) pair. Filled in by the routing-core issue.
