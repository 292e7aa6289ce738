//! A rule of the model as one line of the configuration language, for the statistics:
//! `accept with priority 3 if PING from 1.0/8`. Subnets are written in their shortest
//! form (`1.1`, `1.0/8`, `0.1\8`, or `S.C:M.N` for other masks); a priority written on
//! a `reject` rule is not kept by the model, so it is not shown.

use crate::address::{Address, Subnet};
use crate::config::{Action, Config, Rule};
use crate::dialect::{UNKNOWN_ID, UNKNOWN_NAME};

/// The text of `rule` in `config` (whose chains name `call` and `goto` targets).
pub fn rule_text(config: &Config, rule: &Rule) -> String {
    let chain = |id: crate::config::ChainId| {
        config
            .chains
            .get(id.0)
            .map_or_else(|| format!("#{}", id.0), |c| c.name.clone())
    };
    let mut s = match rule.action {
        Action::Accept => "accept".to_string(),
        Action::Reject => "reject".to_string(),
        Action::Call(c) => format!("call {}", chain(c)),
        Action::Goto(c) => format!("goto {}", chain(c)),
    };
    if let Some(p) = rule.priority {
        s.push_str(&format!(" with priority {p}"));
    }
    if let Some(r) = rule.rate {
        s.push_str(&format!(" with rate {r}"));
    }
    let c = &rule.condition;
    let mut cond = Vec::new();
    match c.signed {
        Some(true) => cond.push("signed".to_string()),
        Some(false) => cond.push("unsigned".to_string()),
        None => {}
    }
    if let Some(id) = c.message_id {
        let name = match config.dialect.by_id(id) {
            Some(m) => m.name.to_string(),
            None if id == UNKNOWN_ID => UNKNOWN_NAME.to_string(),
            None => id.to_string(),
        };
        cond.push(name);
    }
    if let Some(from) = c.source {
        cond.push(format!("from {}", subnet_text(from)));
    }
    if let Some(to) = c.dest {
        cond.push(format!("to {}", subnet_text(to)));
    }
    if !cond.is_empty() {
        s.push_str(" if ");
        s.push_str(&cond.join(" "));
    }
    s
}

/// `subnet` in its shortest form.
pub(crate) fn subnet_text(subnet: Subnet) -> String {
    let a = subnet.address;
    let m = subnet.mask;
    if m == 0xFFFF {
        return a.to_string();
    }
    if m.leading_ones() + m.trailing_zeros() == 16 {
        return format!("{a}/{}", m.leading_ones());
    }
    let c = m & 0xFF;
    if m >> 8 == 0 && (c as u8).leading_ones() + (c as u8).trailing_zeros() == 8 {
        return format!("{a}\\{}", (c as u8).leading_ones());
    }
    format!("{a}:{}", Address::from_u16(m))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules_read_as_written() {
        let src = "chain default {\n accept with priority 3 if PING from 1.0/8;\n call c if signed to 2.2;\n reject with priority 9;\n goto c if HEARTBEAT from 128.0\\1 to 255.0:128.240;\n}\nchain c { accept if unsigned; }";
        let config = crate::config::load(src).expect("loads").config;
        let texts: Vec<_> = config.chains[0]
            .rules
            .iter()
            .map(|r| rule_text(&config, r))
            .collect();
        assert_eq!(
            texts,
            [
                "accept with priority 3 if PING from 1.0/8",
                "call c if signed to 2.2",
                "reject",
                "goto c if HEARTBEAT from 128.0\\1 to 255.0:128.240",
            ]
        );
        assert_eq!(
            rule_text(&config, &config.chains[1].rules[0]),
            "accept if unsigned"
        );
    }
}
