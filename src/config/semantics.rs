//! From syntax tree to [`Config`]: resolves chain and message names, checks every number's
//! range, fills in defaults and rejects `call`/`goto` cycles. Collects every error it
//! finds (in file order) rather than stopping at the first.

use super::ast::{
    self, ActionAst, AddressAst, Ast, Item, MaskAst, QueueSetting, RecordSetting, SerialSetting,
    SubnetAst,
};
use super::claims::Claim;
use super::diagnostic::Diagnostic;
use super::lines::LineIndex;

use super::model::*;
use super::sockets::{self, Kind};
use super::values::{interface_signing, ranged};
use super::{Span, suggest};
use crate::address::{Address, PrefixMask, Subnet};
use crate::dialect::{Dialect, Loader, UNKNOWN_ID, UNKNOWN_NAME};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A valid configuration plus the warnings found while checking it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Loaded {
    /// The configuration.
    pub config: Config,
    /// Things that are allowed but probably not meant (one line each).
    pub warnings: Vec<String>,
}

/// Checks `ast` and builds the configuration, or returns every error found. The
/// `dialect` files it names are read relative to the working directory.
pub fn analyse(ast: &Ast<'_>) -> Result<Loaded, Vec<Diagnostic>> {
    analyse_in(ast, Path::new(""))
}

/// [`analyse`] for a configuration file in directory `dir`: relative `dialect` paths
/// are taken from there.
pub fn analyse_in(ast: &Ast<'_>, dir: &Path) -> Result<Loaded, Vec<Diagnostic>> {
    let mut cx = Checker {
        ast,
        errors: Vec::new(),
        ids: HashMap::new(),
        names: Vec::new(),
        edges: Vec::new(),
        lines: LineIndex::new(ast.src),
        dialect: Dialect::builtin(),
        names_unknown: false,
    };
    cx.register_chains();
    // Dialects first, wherever they are written: rules anywhere may name their messages.
    let dialect_files = cx.load_dialects(dir);
    let mut unknown_messages = UnknownMessages::Reject;
    let mut default_action = DefaultAction::Reject;
    let mut interfaces = Vec::new();
    let mut zenoh_prefixes: Vec<(usize, String)> = Vec::new();
    // What the interfaces so far hold, with the line of their keyword, to catch two
    // claiming one socket or device.
    let mut claimed: Vec<(Claim, usize)> = Vec::new();
    let mut queue = QueueBounds::default();
    // Line of the first `queue` block: a second one is an error.
    let mut queue_line: Option<usize> = None;
    let mut signing_state = None;
    // The `record` block, and the line of the first one: a second one is an error.
    let mut record: Option<Recording> = None;
    let mut record_line: Option<usize> = None;
    let mut stats = None;
    // Line of the first `stats` block: a second one is an error.
    let mut stats_line: Option<usize> = None;
    let mut dedup = None;
    let mut dedup_line: Option<usize> = None;
    let mut heartbeat = None;
    let mut heartbeat_line: Option<usize> = None;
    let mut flight_log = None;
    let mut flight_log_line: Option<usize> = None;
    let mut groups: Vec<InterfaceGroup> = Vec::new();
    let mut chains: Vec<Chain> = cx
        .names
        .iter()
        .map(|(n, _)| Chain {
            name: n.to_string(),
            rules: Vec::new(),
        })
        .collect();
    for item in &ast.items {
        match item {
            Item::DefaultAction { accept, .. } => {
                default_action = if *accept {
                    DefaultAction::Accept
                } else {
                    DefaultAction::Reject
                };
            }
            Item::Udp { keyword, settings }
            | Item::Tcp { keyword, settings }
            | Item::WebSocket { keyword, settings } => {
                let kind = match item {
                    Item::Tcp { .. } => Kind::Tcp,
                    Item::WebSocket { .. } => Kind::WebSocket,
                    _ => Kind::Udp,
                };
                let named: Vec<Span> = (settings.iter())
                    .filter_map(|s| match s {
                        ast::SocketSetting::Group(v) => Some(*v),
                        _ => None,
                    })
                    .collect();
                let group = super::paths::group(ast, &named, &mut cx.errors);
                if let Some(iface) = sockets::check(ast, kind, settings, &mut cx.errors) {
                    cx.no_shared_claim(*keyword, &iface, &mut claimed);
                    if let Some(name) = group {
                        groups.push(InterfaceGroup {
                            interface: interfaces.len(),
                            name,
                        });
                    }
                    interfaces.push(iface);
                }
            }
            Item::Zenoh { keyword, settings } => {
                if let Some(z) = super::zenoh_block::check(ast, *keyword, settings, &mut cx.errors)
                {
                    zenoh_prefixes.push((cx.line(*keyword), z.prefix.clone()));
                    interfaces.push(Interface::Zenoh(z));
                }
            }
            Item::Serial { keyword, settings } => {
                let named: Vec<Span> = (settings.iter())
                    .filter_map(|s| match s {
                        SerialSetting::Group(v) => Some(*v),
                        _ => None,
                    })
                    .collect();
                let group = super::paths::group(ast, &named, &mut cx.errors);
                if let Some(serial) = cx.serial(*keyword, settings) {
                    let serial = Interface::Serial(serial);
                    cx.no_shared_claim(*keyword, &serial, &mut claimed);
                    if let Some(name) = group {
                        groups.push(InterfaceGroup {
                            interface: interfaces.len(),
                            name,
                        });
                    }
                    interfaces.push(serial);
                }
            }
            Item::Queue { keyword, settings } => {
                if let Some(first) = queue_line {
                    cx.error(
                        Diagnostic::new(*keyword, "only one 'queue' block is allowed").with_note(
                            format!(
                                "the first 'queue' block is on line {first}; give both bounds there"
                            ),
                        ),
                    );
                }
                let bounds = cx.queue(settings);
                if queue_line.is_none() {
                    queue_line = Some(cx.line(*keyword));
                    queue = bounds.unwrap_or_default();
                }
            }
            Item::Stats { keyword, settings } => {
                let endpoint = super::stats_block::check(ast, *keyword, settings, &mut cx.errors);
                match stats_line {
                    Some(first) => cx.error(
                        Diagnostic::new(*keyword, "only one 'stats' block is allowed")
                            .with_note(format!("the first 'stats' block is on line {first}")),
                    ),
                    None => {
                        stats_line = Some(cx.line(*keyword));
                        stats = endpoint;
                    }
                }
            }
            Item::SigningState { path, .. } => {
                signing_state = Some(ast.text(*path).to_string());
            }
            Item::Dialect { .. } => {} // loaded above
            Item::UnknownMessages { accept, .. } => {
                unknown_messages = if *accept {
                    UnknownMessages::Accept
                } else {
                    UnknownMessages::Reject
                };
            }
            Item::Record { keyword, settings } => {
                if let Some(first) = record_line {
                    cx.error(
                        Diagnostic::new(*keyword, "only one 'record' block is allowed")
                            .with_note(format!("the first 'record' block is on line {first}")),
                    );
                }
                let only = settings
                    .iter()
                    .filter_map(|s| match s {
                        RecordSetting::Only { condition, .. } => Some(cx.condition(condition)),
                        _ => None,
                    })
                    .collect();
                let checked = super::recording::check(ast, settings, only, &mut cx.errors);
                if record_line.is_none() {
                    record_line = Some(cx.line(*keyword));
                    record = checked;
                }
            }
            Item::Dedup { keyword, value } => {
                let window = super::paths::dedup(ast, *value, &mut cx.errors);
                match dedup_line {
                    Some(first) => cx.error(
                        Diagnostic::new(*keyword, "only one 'dedup' statement is allowed")
                            .with_note(format!("the first 'dedup' statement is on line {first}")),
                    ),
                    None => {
                        dedup_line = Some(cx.line(*keyword));
                        dedup = window;
                    }
                }
            }
            Item::Heartbeat { keyword, settings } => {
                let checked = super::paths::heartbeat(ast, settings, &mut cx.errors);
                match heartbeat_line {
                    Some(first) => cx.error(
                        Diagnostic::new(*keyword, "only one 'heartbeat' block is allowed")
                            .with_note(format!("the first 'heartbeat' block is on line {first}")),
                    ),
                    None => {
                        heartbeat_line = Some(cx.line(*keyword));
                        heartbeat = checked;
                    }
                }
            }
            Item::FlightLog { keyword, settings } => {
                let checked = super::flight_log::check(ast, settings, &mut cx.errors);
                match flight_log_line {
                    Some(first) => cx.error(
                        Diagnostic::new(*keyword, "only one 'flight_log' block is allowed")
                            .with_note(format!("the first 'flight_log' block is on line {first}")),
                    ),
                    None => {
                        flight_log_line = Some(cx.line(*keyword));
                        flight_log = checked;
                    }
                }
            }
            Item::Chain { name, rules } => {
                let id = cx.ids[ast.text(*name)];
                for rule in rules {
                    if let Some(rule) = cx.rule(id, rule) {
                        chains[id.0].rules.push(rule);
                    }
                }
            }
        }
    }
    let mut warnings = Vec::new();
    let default_chain = match cx.ids.get("default") {
        Some(id) => *id,
        None => {
            let action = match default_action {
                DefaultAction::Accept => "accept",
                DefaultAction::Reject => "reject",
            };
            warnings.push(format!(
                "no 'default' chain is defined, so every packet gets the default action ({action})"
            ));
            chains.push(Chain {
                name: "default".to_string(),
                rules: Vec::new(),
            });
            ChainId(chains.len() - 1)
        }
    };
    if cx.names_unknown && unknown_messages == UnknownMessages::Reject {
        warnings.push(format!(
            "rules name {UNKNOWN_NAME}, which matches nothing unless 'unknown_messages accept;' is set"
        ));
    }
    warnings.extend(super::paths::lonely_groups(&groups));
    warnings.extend(super::zenoh_block::overlapping(&zenoh_prefixes));
    cx.find_cycles();
    if !cx.errors.is_empty() {
        return Err(cx.errors);
    }
    Ok(Loaded {
        config: Config {
            default_action,
            interfaces,
            chains,
            default_chain,
            queue,
            signing_state,
            record,
            stats,
            dialect: cx.dialect,
            dialect_files,
            unknown_messages,
            dedup,
            groups,
            heartbeat,
            flight_log,
        },
        warnings,
    })
}

/// A `call`/`goto` reference from one chain to another.
struct ChainRef {
    from: ChainId,
    to: ChainId,
    at: Span,
    goto: bool,
}

struct Checker<'a, 'b> {
    ast: &'b Ast<'a>,
    errors: Vec<Diagnostic>,
    ids: HashMap<&'a str, ChainId>,
    names: Vec<(&'a str, Span)>,
    edges: Vec<ChainRef>,
    lines: LineIndex,
    /// The messages rules may name: built in, and from the `dialect` files.
    dialect: Dialect,
    /// A rule or `only` condition names `UNKNOWN`.
    names_unknown: bool,
}

impl<'a> Checker<'a, '_> {
    fn text(&self, span: Span) -> &'a str {
        self.ast.text(span)
    }

    fn error(&mut self, d: Diagnostic) {
        self.errors.push(d);
    }

    fn line(&self, span: Span) -> usize {
        self.lines.line_of(span.start)
    }

    /// Every chain name first, so chains can be used before their definition.
    fn register_chains(&mut self) {
        for item in &self.ast.items {
            if let Item::Chain { name, .. } = item {
                let text = self.text(*name);
                if !self.ids.contains_key(text) {
                    self.ids.insert(text, ChainId(self.names.len()));
                    self.names.push((text, *name));
                }
            }
        }
    }

    /// Two interfaces cannot hold one local socket or one serial device: the second
    /// could not be bound, or they would split a device's bytes between them.
    fn no_shared_claim(
        &mut self,
        keyword: Span,
        iface: &Interface,
        seen: &mut Vec<(Claim, usize)>,
    ) {
        let Some(claim) = Claim::of(iface) else {
            return;
        };
        if let Some((other, first)) = seen.iter().find(|(c, _)| c.clashes(&claim)) {
            let d = match &claim {
                Claim::Device(device) => Diagnostic::new(
                    keyword,
                    format!(
                        "serial device '{device}' is already used by the serial interface on line {first}"
                    ),
                )
                .with_note("each device can belong to one serial block only"),
                _ => {
                    let (kind, other_kind) = (claim.kind(), other.kind());
                    Diagnostic::new(
                        keyword,
                        format!(
                            "{kind} interface {claim} clashes with the {other_kind} interface on line {first} ({other})"
                        ),
                    )
                    .with_note("two interfaces cannot listen on one port of one address; give this one another port")
                }
            };
            self.error(d);
        }
        seen.push((claim, self.line(keyword)));
    }

    /// The bounds of a `queue` block; every bad value is reported.
    fn queue(&mut self, settings: &[QueueSetting]) -> Option<QueueBounds> {
        let mut bounds = QueueBounds::default();
        let mut total_at = None;
        let mut ok = true;
        for s in settings {
            let (span, name, slot) = match s {
                QueueSetting::LinkBytes(v) => (*v, "link_bytes", &mut bounds.link_bytes),
                QueueSetting::TotalBytes(v) => {
                    total_at = Some(*v);
                    (*v, "total_bytes", &mut bounds.total_bytes)
                }
            };
            match self.queue_bytes(span, name) {
                Some(bytes) => *slot = Some(bytes),
                None => ok = false,
            }
        }
        if let (Some(link), Some(total), Some(at)) =
            (bounds.link_bytes, bounds.total_bytes, total_at)
            && total < link
        {
            self.error(
                Diagnostic::new(
                    at,
                    format!("total_bytes ({total}) must be at least link_bytes ({link})"),
                )
                .with_note("all queues together need room for at least one full link queue"),
            );
            ok = false;
        }
        ok.then_some(bounds)
    }

    /// A queue bound in bytes, from one largest frame with its bookkeeping up to 2^40.
    fn queue_bytes(&mut self, span: Span, name: &str) -> Option<usize> {
        let (min, max) = (QueueBounds::MIN_BYTES, QueueBounds::MAX_BYTES);
        let max = max.min(u64::try_from(usize::MAX).unwrap_or(u64::MAX));
        let text = self.text(span);
        match super::values::byte_count(text) {
            Some(v) if (min..=max).contains(&v) => usize::try_from(v).ok(),
            _ => {
                self.error(
                    Diagnostic::new(
                        span,
                        format!("{name} ({text}) is outside of the allowed range ({min} - {max})"),
                    )
                    .with_note(
                        "a queue needs room for one largest frame (280 bytes) and its 32 bytes of bookkeeping; the most is 2^40 bytes",
                    ),
                );
                None
            }
        }
    }

    fn serial(&mut self, keyword: Span, settings: &[SerialSetting]) -> Option<SerialInterface> {
        let mut device = None;
        let mut serial = SerialInterface {
            device: String::new(),
            baudrate: 9600,
            flow_control: false,
            preload: Vec::new(),
            max_bitrate: None,
            signing: None,
        };
        let mut key_file = None;
        let mut allow_unsigned = Vec::new();
        let mut ok = true;
        for s in settings {
            match s {
                SerialSetting::Device(v) => device = Some(self.text(*v).to_string()),
                SerialSetting::Baudrate(v) => {
                    match self.unsigned(*v, 1, u32::MAX.into(), "baud rate") {
                        Some(b) => serial.baudrate = b as u32,
                        None => ok = false,
                    }
                }
                SerialSetting::FlowControl { enabled, .. } => serial.flow_control = *enabled,
                SerialSetting::Preload(a) => match self.address(a) {
                    Some(a) => serial.preload.push(a),
                    None => ok = false,
                },
                SerialSetting::MaxBitrate(v) => match self.unsigned(*v, 0, u64::MAX, "bitrate") {
                    Some(b) => serial.max_bitrate = (b > 0).then_some(b),
                    None => ok = false,
                },
                SerialSetting::SigningKey(v) => key_file = Some(*v),
                SerialSetting::AllowUnsigned(v) => allow_unsigned.push(*v),
                SerialSetting::Group(_) => {} // see `super::paths::group`
            }
        }
        match interface_signing(self.ast, key_file, &allow_unsigned) {
            Ok(signing) => serial.signing = signing,
            Err(d) => {
                self.error(d);
                ok = false;
            }
        }
        match device {
            Some(d) => serial.device = d,
            None => {
                self.error(Diagnostic::new(keyword, "missing device string").with_note(
                    "a serial block needs a 'device' statement, e.g. 'device /dev/ttyUSB0;'",
                ));
                ok = false;
            }
        }
        ok.then_some(serial)
    }

    /// A decimal number within `min..=max`, or an error naming `what`.
    fn unsigned(&mut self, span: Span, min: u64, max: u64, what: &str) -> Option<u64> {
        let text = self.text(span);
        ranged(text, min, max, what)
            .map_err(|message| self.error(Diagnostic::new(span, message)))
            .ok()
    }

    /// One part of a MAVLink address (0..=255), named `System` or `Component`.
    fn id_part(&mut self, span: Span, what: &str) -> Option<u8> {
        let text = self.text(span);
        match text.parse::<u8>() {
            Ok(v) => Some(v),
            Err(_) => {
                self.error(Diagnostic::new(
                    span,
                    format!("{what} ID ({text}) is outside of the allowed range (0 - 255)."),
                ));
                None
            }
        }
    }

    fn address(&mut self, a: &AddressAst) -> Option<Address> {
        let system = self.id_part(a.system, "System");
        let component = self.id_part(a.component, "Component");
        Some(Address::new(system?, component?))
    }

    fn subnet(&mut self, s: &SubnetAst) -> Option<Subnet> {
        let address = self.address(&s.address);
        match s.mask {
            MaskAst::Exact => Some(Subnet::exact(address?)),
            MaskAst::Explicit(mask) => {
                let mask = self.address(&mask);
                Some(Subnet::new(address?, mask?))
            }
            MaskAst::Slash(bits) => self.prefix_masked(address, PrefixMask::Slash, bits),
            MaskAst::Backslash(bits) => self.prefix_masked(address, PrefixMask::Backslash, bits),
        }
    }

    /// `address` under the bit count written at `bits` (`/n` or `\n`); the bit count is
    /// checked even when the address was wrong, so both errors are reported.
    fn prefix_masked(
        &mut self,
        address: Option<Address>,
        form: PrefixMask,
        bits: Span,
    ) -> Option<Subnet> {
        match form.bits(self.text(bits)) {
            Ok(n) => form.subnet(address?, n),
            Err(message) => {
                self.error(Diagnostic::new(bits, message));
                None
            }
        }
    }

    fn rule(&mut self, chain: ChainId, rule: &ast::Rule) -> Option<Rule> {
        let action = match rule.action {
            ActionAst::Accept => Some(Action::Accept),
            ActionAst::Reject => Some(Action::Reject),
            ActionAst::Call(target) => self.target(chain, target, false).map(Action::Call),
            ActionAst::Goto(target) => self.target(chain, target, true).map(Action::Goto),
        };
        let priority = match rule.priority {
            None => Some(None),
            Some(span) => {
                let text = self.text(span);
                match text.parse::<i64>().ok().and_then(|v| i32::try_from(v).ok()) {
                    Some(p) => Some(Some(p)),
                    None => {
                        self.error(Diagnostic::new(
                            span,
                            format!(
                                "priority level ({text}) is outside of the allowed range ({} - {})",
                                i32::MIN,
                                i32::MAX
                            ),
                        ));
                        None
                    }
                }
            }
        };
        let condition = match &rule.condition {
            None => Some(Condition::default()),
            Some(c) => self.condition(c),
        };
        let rate = self.rule_rate(rule);
        let action = action?;
        let priority = if action == Action::Reject {
            None
        } else {
            priority?
        };
        Some(Rule {
            action,
            priority,
            condition: condition?,
            rate: rate?,
        })
    }

    /// The rate of `with rate N/UNIT`: valid, and on an `accept` rule only.
    fn rule_rate(&mut self, rule: &ast::Rule) -> Option<Option<Rate>> {
        let Some(r) = rule.rate else {
            return Some(None);
        };
        if !matches!(rule.action, ActionAst::Accept) {
            self.error(
                Diagnostic::new(r.keyword, "a rate applies to 'accept' rules only")
                    .with_note("put the rate on the 'accept' rule that lets the packets through"),
            );
            return None;
        }
        match Rate::parse(self.text(r.count), self.text(r.unit)) {
            Ok(rate) => Some(Some(rate)),
            Err(message) => {
                self.error(Diagnostic::new(r.span, message));
                None
            }
        }
    }

    fn target(&mut self, from: ChainId, target: Span, goto: bool) -> Option<ChainId> {
        let name = self.text(target);
        let verb = if goto { "goto" } else { "call" };
        if name == "default" {
            self.error(Diagnostic::new(
                target,
                format!("cannot '{verb}' the default chain"),
            ));
            return None;
        }
        match self.ids.get(name) {
            Some(id) => {
                self.edges.push(ChainRef {
                    from,
                    to: *id,
                    at: target,
                    goto,
                });
                Some(*id)
            }
            None => {
                let mut d = Diagnostic::new(target, format!("chain '{name}' is not defined"));
                let names: Vec<&str> = self.names.iter().map(|(n, _)| *n).collect();
                if let Some(note) = suggest::did_you_mean(name, names) {
                    d = d.with_note(note);
                }
                self.error(d);
                None
            }
        }
    }

    fn condition(&mut self, c: &ast::ConditionAst) -> Option<Condition> {
        let message_id = match c.packet_type {
            None => Some(None),
            Some(span) => {
                let name = self.text(span);
                match self.dialect.by_name(name) {
                    Some(info) => Some(Some(info.id)),
                    None if name == UNKNOWN_NAME => {
                        self.names_unknown = true;
                        Some(Some(UNKNOWN_ID))
                    }
                    None => {
                        let mut d =
                            Diagnostic::new(span, format!("Invalid packet name (\"{name}\")."));
                        if let Some(note) = suggest::did_you_mean(name, self.dialect.names()) {
                            d = d.with_note(note);
                        }
                        self.error(d);
                        None
                    }
                }
            }
        };
        let source = match &c.source {
            None => Some(None),
            Some(s) => self.subnet(s).map(Some),
        };
        let dest = match &c.dest {
            None => Some(None),
            Some(s) => self.subnet(s).map(Some),
        };
        Some(Condition {
            signed: c.signed.map(|(_, signed)| signed),
            message_id: message_id?,
            source: source?,
            dest: dest?,
        })
    }

    /// Loads the files of the `dialect` statements (relative ones from `dir`) into
    /// `self.dialect`; a file that cannot be loaded is an error at its statement.
    /// Returns the files, resolved.
    fn load_dialects(&mut self, dir: &Path) -> Vec<PathBuf> {
        let mut loader = Loader::new();
        let mut files = Vec::new();
        for item in &self.ast.items {
            let Item::Dialect { path, .. } = item else {
                continue;
            };
            let written = Path::new(self.text(*path));
            let file = dir.join(written);
            if let Err(e) = loader.add(&file) {
                let mut d = Diagnostic::new(*path, format!("cannot load the dialect: {e}"));
                if written.is_relative() {
                    let dir = match dir.to_str() {
                        Some("") => ".".to_string(),
                        _ => dir.display().to_string(),
                    };
                    d = d.with_note(format!(
                        "a relative path is taken from the configuration file's directory ({dir})"
                    ));
                }
                self.error(d);
            }
            files.push(file);
        }
        self.dialect = loader.finish();
        files
    }

    /// Reports every `call`/`goto` loop (found by an iterative depth-first search, so a
    /// long chain of chains cannot overflow the stack).
    fn find_cycles(&mut self) {
        let n = self.names.len();
        let mut out: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (i, e) in self.edges.iter().enumerate() {
            out[e.from.0].push(i);
        }
        #[derive(Clone, Copy, PartialEq)]
        enum State {
            New,
            Open,
            Done,
        }
        let mut state = vec![State::New; n];
        let mut found: Vec<Vec<usize>> = Vec::new();
        for root in 0..n {
            if state[root] != State::New {
                continue;
            }
            // (chain, next outgoing edge to look at); path[i] leads from stack[i] to stack[i+1].
            let mut stack: Vec<(usize, usize)> = vec![(root, 0)];
            let mut path: Vec<usize> = Vec::new();
            state[root] = State::Open;
            while let Some(top) = stack.last_mut() {
                let node = top.0;
                if let Some(&edge) = out[node].get(top.1) {
                    top.1 += 1;
                    let to = self.edges[edge].to.0;
                    match state[to] {
                        State::New => {
                            state[to] = State::Open;
                            stack.push((to, 0));
                            path.push(edge);
                        }
                        State::Open => {
                            let k = stack.iter().position(|(c, _)| *c == to).unwrap_or(0);
                            let mut cycle = path[k..].to_vec();
                            cycle.push(edge);
                            found.push(cycle);
                        }
                        State::Done => {}
                    }
                } else {
                    state[node] = State::Done;
                    stack.pop();
                    path.pop();
                }
            }
        }
        for cycle in found {
            self.report_cycle(&cycle);
        }
    }

    fn report_cycle(&mut self, cycle: &[usize]) {
        let Some(&first) = cycle.first() else { return };
        let mut names = vec![self.names[self.edges[first].from.0].0];
        let mut notes = Vec::new();
        for &i in cycle {
            let e = &self.edges[i];
            let (from, to) = (self.names[e.from.0].0, self.names[e.to.0].0);
            names.push(to);
            let verb = if e.goto { "goes to" } else { "calls" };
            notes.push(format!(
                "line {}: chain '{from}' {verb} '{to}'",
                self.line(e.at)
            ));
        }
        let mut d = Diagnostic::new(
            self.edges[first].at,
            format!("call/goto cycle: {}", names.join(" -> ")),
        );
        for note in notes {
            d = d.with_note(note);
        }
        self.error(d);
    }
}
