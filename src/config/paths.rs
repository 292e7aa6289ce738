//! The meaning of the redundant-path statements: `dedup DURATION;`, the `group NAME;`
//! of interface blocks, and the router's own `heartbeat { ... }`. Each value is checked
//! and located; every error is collected.

use std::collections::BTreeMap;
use std::time::Duration;

use super::Span;
use super::ast::{Ast, HeartbeatSetting};
use super::diagnostic::Diagnostic;
use super::values::mavlink_id;

/// The shortest `dedup` window.
pub const MIN_DEDUP: Duration = Duration::from_millis(1);
/// The longest `dedup` window: duplicates over redundant radios arrive within a second;
/// a longer window only risks dropping genuine resends.
pub const MAX_DEDUP: Duration = Duration::from_secs(10);
/// The shortest heartbeat interval.
pub const MIN_HEARTBEAT: Duration = Duration::from_millis(10);
/// The longest heartbeat interval.
pub const MAX_HEARTBEAT: Duration = Duration::from_secs(3600);

/// The `heartbeat { system N; component N; interval DURATION; }` block: the router
/// sends its own HEARTBEAT to every link at this interval.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Heartbeat {
    /// The router's system id (default 1).
    pub system: u8,
    /// The router's component id (default 191, MAV_COMP_ID_ONBOARD_COMPUTER).
    pub component: u8,
    /// Time between two heartbeats (default 1 s).
    pub interval: Duration,
}

impl Default for Heartbeat {
    fn default() -> Self {
        Heartbeat {
            system: 1,
            component: 191,
            interval: Duration::from_secs(1),
        }
    }
}

/// One `group NAME;` statement: the `interface`th block of the configuration (index
/// into [`Config::interfaces`](super::Config::interfaces)) is in group `name`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InterfaceGroup {
    /// Index of the interface in the configuration.
    pub interface: usize,
    /// The group's name.
    pub name: String,
}

/// `text` as a duration: a whole number and a unit `ms`, `s` or `min`.
pub(crate) fn duration(text: &str) -> Result<Duration, String> {
    let digits = text
        .find(|c: char| !c.is_ascii_digit())
        .unwrap_or(text.len());
    let (number, unit) = text.split_at(digits);
    let n: u64 = number
        .parse()
        .map_err(|_| format!("expected a duration, found '{text}'"))?;
    match unit {
        "ms" => Ok(Duration::from_millis(n)),
        "s" => Ok(Duration::from_secs(n)),
        "min" => Ok(Duration::from_secs(n.saturating_mul(60))),
        _ => Err(format!(
            "unknown unit '{unit}' in duration '{text}': use ms, s or min"
        )),
    }
}

/// A written duration within `min..=max`, or the error at `span`.
fn ranged_duration(
    ast: &Ast<'_>,
    span: Span,
    min: Duration,
    max: Duration,
    what: &str,
) -> Result<Duration, Diagnostic> {
    let text = ast.text(span);
    let d = duration(text).map_err(|m| Diagnostic::new(span, m))?;
    if d < min || d > max {
        return Err(Diagnostic::new(
            span,
            format!(
                "{what} ({text}) is outside of the allowed range ({} - {})",
                show(min),
                show(max)
            ),
        ));
    }
    Ok(d)
}

fn show(d: Duration) -> String {
    if d.subsec_millis() != 0 || d.as_secs() == 0 {
        format!("{}ms", d.as_millis())
    } else {
        format!("{}s", d.as_secs())
    }
}

/// The window of a `dedup` statement.
pub(crate) fn dedup(ast: &Ast<'_>, value: Span, errors: &mut Vec<Diagnostic>) -> Option<Duration> {
    ranged_duration(ast, value, MIN_DEDUP, MAX_DEDUP, "dedup window")
        .map_err(|d| {
            errors.push(d.with_note(
                "the window is how long a frame's copy is dropped; radios deliver copies within a second",
            ))
        })
        .ok()
}

/// The settings of a `heartbeat` block; `None` after reporting its errors.
pub(crate) fn heartbeat(
    ast: &Ast<'_>,
    settings: &[HeartbeatSetting],
    errors: &mut Vec<Diagnostic>,
) -> Option<Heartbeat> {
    let mut hb = Heartbeat::default();
    let mut ok = true;
    let mut fail = |d: Diagnostic| {
        errors.push(d);
        ok = false;
    };
    for s in settings {
        match *s {
            HeartbeatSetting::System(v) => match mavlink_id(ast.text(v), "system id") {
                Ok(n) => hb.system = n,
                Err(m) => fail(Diagnostic::new(v, m)),
            },
            HeartbeatSetting::Component(v) => match mavlink_id(ast.text(v), "component id") {
                Ok(n) => hb.component = n,
                Err(m) => fail(Diagnostic::new(v, m)),
            },
            HeartbeatSetting::Interval(v) => {
                match ranged_duration(ast, v, MIN_HEARTBEAT, MAX_HEARTBEAT, "heartbeat interval") {
                    Ok(d) => hb.interval = d,
                    Err(d) => fail(d),
                }
            }
        }
    }
    ok.then_some(hb)
}

/// The group of one interface block from its `group` statements: one at most.
pub(crate) fn group(
    ast: &Ast<'_>,
    statements: &[Span],
    errors: &mut Vec<Diagnostic>,
) -> Option<String> {
    let first = *statements.first()?;
    for extra in &statements[1..] {
        let line = super::Position::of(ast.src, first.start).line;
        errors.push(
            Diagnostic::new(*extra, "an interface belongs to one group only")
                .with_note(format!("its group is named on line {line}")),
        );
    }
    Some(ast.text(first).to_string())
}

/// Warnings for groups of one interface: a group is redundant paths to one vehicle.
pub(crate) fn lonely_groups(groups: &[InterfaceGroup]) -> Vec<String> {
    let mut count: BTreeMap<&str, usize> = BTreeMap::new();
    for g in groups {
        *count.entry(&g.name).or_default() += 1;
    }
    count
        .into_iter()
        .filter(|(_, n)| *n == 1)
        .map(|(name, _)| {
            format!(
                "group '{name}' has one interface: a group joins two or more paths to a vehicle"
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations() {
        assert_eq!(duration("500ms"), Ok(Duration::from_millis(500)));
        assert_eq!(duration("1s"), Ok(Duration::from_secs(1)));
        assert_eq!(duration("2min"), Ok(Duration::from_secs(120)));
        assert!(duration("5h").is_err());
        assert!(duration("ms").is_err());
        assert!(duration("99999999999999999999s").is_err());
    }
}
