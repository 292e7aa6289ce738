//! The sans-IO routing core: address learning, per-link decisions, priority queues and
//! bitrate pacing. It takes packets, link identities and time in, and gives decisions out.
//! Filled in by the routing-core issue.
