//! The configuration's redundant paths and the router's own heartbeat, applied at
//! start and at every reload: the `dedup` window, the `group` of each interface (and of
//! its links and accepted connections), and the `heartbeat` schedule with the router's
//! own address.

use std::collections::HashMap;
use std::sync::Arc;

use super::Engine;
use crate::config::Config;
use crate::routing::Timestamp;
use crate::routing::interface::Kind;
use crate::routing::link::{GroupId, LinkId};
use crate::routing::own_heartbeat::OwnHeartbeat;

impl Engine {
    /// Takes `config`'s `dedup`, groups and `heartbeat` (after its interfaces were
    /// matched: `self.configured` is the new configuration's).
    pub(super) fn apply_paths(&mut self, config: &Config, now: Timestamp) {
        self.core.router.dedup_mut().set_window(config.dedup);
        self.heartbeat = match (self.heartbeat.take(), &config.heartbeat) {
            (_, None) => None,
            (Some(mut running), Some(h)) => {
                running.reconfigure(h);
                Some(running)
            }
            (None, Some(h)) => Some(OwnHeartbeat::new(h, now)),
        };
        self.core
            .router
            .set_own_address(self.heartbeat.as_ref().map(OwnHeartbeat::address));
        self.apply_flight_log(config, now);
        let mut numbers: HashMap<&str, GroupId> = HashMap::new();
        let mut group_of: Vec<Option<GroupId>> = vec![None; config.interfaces.len()];
        for g in &config.groups {
            let next = GroupId(u16::try_from(numbers.len()).unwrap_or(u16::MAX));
            let id = *numbers.entry(g.name.as_str()).or_insert(next);
            if let Some(slot) = group_of.get_mut(g.interface) {
                *slot = Some(id);
            }
        }
        let configured: Vec<_> = self.configured.iter().map(|c| c.id()).collect();
        for (n, id) in configured.into_iter().enumerate() {
            let group = group_of.get(n).copied().flatten();
            for member in self.family(id) {
                let Some(interface) = self.interfaces.get_mut(member.0) else {
                    continue;
                };
                interface.group = group;
                let links: Vec<LinkId> = match &interface.kind {
                    Kind::Datagram { remotes, .. } => remotes.iter().map(|(l, _)| l).collect(),
                    Kind::Stream { link, .. } | Kind::DatagramClient { link, .. } => vec![*link],
                    Kind::Listener { .. } => Vec::new(),
                };
                for link in links {
                    self.core.router.set_group(link, group);
                }
            }
        }
    }

    /// Queues the router's heartbeat on every link when it is due at `now`.
    pub(super) fn send_heartbeat(&mut self, now: Timestamp) {
        if let Some(frame) = self.heartbeat.as_mut().and_then(|h| h.take(now)) {
            self.core
                .router
                .queue_own(&Arc::from(frame), &mut self.core.out);
        }
    }
}
