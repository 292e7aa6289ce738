//! Reports: the statistics snapshot, the counters report and idleness at shutdown.

use super::*;

impl Engine {
    /// True if interface `id` has nothing queued that it could send (a closed stream
    /// can send nothing).
    pub fn is_idle(&self, id: InterfaceId) -> bool {
        let Some(interface) = self.interfaces.get(id.0) else {
            return true;
        };
        match &interface.kind {
            Kind::Datagram { remotes, .. } => remotes
                .iter()
                .all(|(l, _)| self.core.router.peek(l).is_none()),
            Kind::Stream { .. } | Kind::DatagramClient { .. } => {
                !interface.is_open()
                    || interface
                        .own_link()
                        .is_none_or(|l| self.core.router.peek(l).is_none())
            }
            Kind::Listener { .. } => true,
        }
    }

    /// Every counter at `now`, with the rates since the previous call (take one about
    /// once a second: each call is a sample of the rate history).
    pub fn stats(&mut self, now: Timestamp) -> StatsSnapshot {
        self.settle_direct();
        snapshot::snapshot(
            snapshot::Sources {
                router: &mut self.core.router,
                interfaces: &self.interfaces,
                rules: &self.rules,
                history: &mut self.history,
            },
            now,
        )
    }

    /// The counters of every link (in creation order) and every interface, one line
    /// each, under a `mavtables counters:` heading.
    pub fn report(&self) -> String {
        let mut text = String::from("mavtables counters:\n");
        for link in self.core.router.links() {
            text.push_str(&format!("  {}\n", link.report()));
        }
        for (_, i) in &self.interfaces {
            let mut parser = *i.parser.stats();
            parser += i.closed_parsers;
            let line = InterfaceReport {
                label: &i.label,
                parser: &parser,
                io_errors: i.io_errors,
                refused: i.refused,
                signing: i.signing.as_ref().map(|e| e.counters),
            };
            text.push_str(&format!("  {line}\n"));
        }
        text
    }
}
