//! MAVLink subnets: an address plus a 16-bit mask, like an IP subnet over `system.component`.

use super::Address;
use std::fmt;

/// A set of MAVLink addresses: every address whose masked bits equal the subnet's masked bits.
///
/// The mask is 16 bits wide with the system id in the high byte, so `255.0` matches on the
/// system only. The stored address is kept as written (not pre-masked).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Subnet {
    /// The address the subnet was written with.
    pub address: Address,
    /// Which bits must match (system in the high byte, component in the low byte).
    pub mask: u16,
}

impl Subnet {
    /// A subnet from an address and an explicit `system.component` mask.
    pub const fn new(address: Address, mask: Address) -> Self {
        Subnet {
            address,
            mask: mask.to_u16(),
        }
    }

    /// The subnet holding exactly one address (the `S.C` form, same as `S.C/16`).
    pub const fn exact(address: Address) -> Self {
        Subnet {
            address,
            mask: 0xFFFF,
        }
    }

    /// The `S.C/bits` form: the leftmost `bits` (0..=16) of the 16-bit address must match.
    /// `None` when `bits` is above 16.
    pub const fn with_prefix(address: Address, bits: u8) -> Option<Self> {
        if bits > 16 {
            return None;
        }
        let mask = if bits == 0 {
            0
        } else {
            u16::MAX << (16 - bits)
        };
        Some(Subnet { address, mask })
    }

    /// The `S.C\bits` form: the system is ignored and the leftmost `bits` (0..=8) of the
    /// component must match. `None` when `bits` is above 8.
    pub(crate) const fn with_component_prefix(address: Address, bits: u8) -> Option<Self> {
        if bits > 8 {
            return None;
        }
        let mask = if bits == 0 {
            0
        } else {
            (u8::MAX << (8 - bits)) as u16
        };
        Some(Subnet { address, mask })
    }

    /// Whether `address` lies in this subnet.
    #[inline]
    pub(crate) const fn contains(&self, address: Address) -> bool {
        address.to_u16() & self.mask == self.address.to_u16() & self.mask
    }
}

/// The two short mask forms, which count leading bits: `S.C/bits` over the whole
/// 16-bit address and `S.C\bits` over the component only. The configuration language
/// and the command-line options read the bit count here, so both accept the same values
/// and give the same error texts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PrefixMask {
    /// `/bits`: the leftmost 0–16 bits of the whole address must match.
    Slash,
    /// `\bits`: the system is ignored; the leftmost 0–8 bits of the component must match.
    Backslash,
}

impl PrefixMask {
    /// The largest bit count this form allows.
    pub(crate) const fn max_bits(self) -> u8 {
        match self {
            PrefixMask::Slash => 16,
            PrefixMask::Backslash => 8,
        }
    }

    /// The bit count written after the `/` or `\` (decimal digits only), or the error
    /// text to show for it, e.g. `Forward slash mask (17) is outside of allowed range
    /// (0 - 16).` (the original mavtables' wording).
    pub(crate) fn bits(self, text: &str) -> Result<u8, String> {
        let max = self.max_bits();
        match text.parse::<u8>() {
            Ok(n) if n <= max && text.bytes().all(|b| b.is_ascii_digit()) => Ok(n),
            _ => {
                let name = match self {
                    PrefixMask::Slash => "Forward slash",
                    PrefixMask::Backslash => "Backslash",
                };
                Err(format!(
                    "{name} mask ({text}) is outside of allowed range (0 - {max})."
                ))
            }
        }
    }

    /// The subnet of `address` under `bits` of this form; `None` when `bits` is above
    /// [`PrefixMask::max_bits`].
    pub(crate) const fn subnet(self, address: Address, bits: u8) -> Option<Subnet> {
        match self {
            PrefixMask::Slash => Subnet::with_prefix(address, bits),
            PrefixMask::Backslash => Subnet::with_component_prefix(address, bits),
        }
    }
}

/// Why a subnet written on the command line could not be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SubnetParseError(pub String);

impl fmt::Display for SubnetParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for SubnetParseError {}

/// Parses `S.C` as two octets.
fn octets(text: &str, whole: &str) -> Result<Address, SubnetParseError> {
    let (s, c) = text.split_once('.').ok_or_else(|| invalid(whole))?;
    let num = |t: &str| -> Result<u8, SubnetParseError> {
        if t.is_empty() || !t.bytes().all(|b| b.is_ascii_digit()) {
            return Err(invalid(whole));
        }
        t.parse::<u8>().map_err(|_| invalid(whole))
    };
    Ok(Address::new(num(s)?, num(c)?))
}

/// The error for a subnet that is not one of the four written forms.
fn invalid(whole: &str) -> SubnetParseError {
    SubnetParseError(format!("Invalid MAVLink subnet: \"{whole}\"."))
}

/// The four written forms of the configuration language, for command-line options:
/// `S.C`, `S.C:M.M`, `S.C/bits` (0–16) and `S.C\bits` (0–8).
impl std::str::FromStr for Subnet {
    type Err = SubnetParseError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        if let Some((addr, mask)) = text.split_once(':') {
            return Ok(Subnet::new(octets(addr, text)?, octets(mask, text)?));
        }
        for (separator, form) in [('/', PrefixMask::Slash), ('\\', PrefixMask::Backslash)] {
            if let Some((addr, bits)) = text.split_once(separator) {
                let bits = form.bits(bits).map_err(SubnetParseError)?;
                return form
                    .subnet(octets(addr, text)?, bits)
                    .ok_or_else(|| invalid(text));
            }
        }
        Ok(Subnet::exact(octets(text, text)?))
    }
}

impl fmt::Display for Subnet {
    /// Always the explicit form `S.C:M.M`, which round-trips through the config language.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.address, Address::from_u16(self.mask))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn a(s: u8, c: u8) -> Address {
        Address::new(s, c)
    }

    #[test]
    fn slash_masks_follow_the_table() {
        let cases = [
            (16, 0xFFFF),
            (15, 0xFFFE),
            (9, 0xFF80),
            (8, 0xFF00),
            (1, 0x8000),
            (0, 0),
        ];
        for (bits, mask) in cases {
            assert_eq!(
                Subnet::with_prefix(a(0, 0), bits).map(|s| s.mask),
                Some(mask)
            );
        }
        assert_eq!(Subnet::with_prefix(a(0, 0), 17), None);
    }

    #[test]
    fn backslash_masks_follow_the_table() {
        let cases = [(8, 0x00FF), (7, 0x00FE), (1, 0x0080), (0, 0)];
        for (bits, mask) in cases {
            assert_eq!(
                Subnet::with_component_prefix(a(0, 0), bits).map(|s| s.mask),
                Some(mask)
            );
        }
        assert_eq!(Subnet::with_component_prefix(a(0, 0), 9), None);
    }

    #[test]
    fn containment_examples() {
        // 1.255/9: system 1, component 128 and above.
        let s = Subnet::with_prefix(a(1, 255), 9).unwrap();
        assert!(s.contains(a(1, 128)) && s.contains(a(1, 255)));
        assert!(!s.contains(a(1, 127)) && !s.contains(a(2, 200)));
        // 192.0/8: any component of system 192.
        let s = Subnet::with_prefix(a(192, 0), 8).unwrap();
        assert!(s.contains(a(192, 7)) && !s.contains(a(193, 7)));
        // 128.0\1: any system, component 127 and below.
        let s = Subnet::with_component_prefix(a(128, 0), 1).unwrap();
        assert!(s.contains(a(5, 127)) && !s.contains(a(5, 128)));
        // 255.0:128.240: system 128 and above, components 0-15.
        let s = Subnet::new(a(255, 0), a(128, 240));
        assert!(s.contains(a(128, 15)) && s.contains(a(200, 0)));
        assert!(!s.contains(a(127, 0)) && !s.contains(a(128, 16)));
        // Exact and match-everything forms.
        assert!(Subnet::exact(a(3, 4)).contains(a(3, 4)));
        assert!(!Subnet::exact(a(3, 4)).contains(a(3, 5)));
        assert!(Subnet::with_prefix(a(9, 9), 0).unwrap().contains(a(1, 2)));
        assert!(
            Subnet::with_component_prefix(a(9, 9), 0)
                .unwrap()
                .contains(a(1, 2))
        );
    }

    #[test]
    fn displays_in_explicit_form() {
        assert_eq!(
            Subnet::with_prefix(a(192, 0), 8).unwrap().to_string(),
            "192.0:255.0"
        );
    }

    #[test]
    fn written_forms_parse_like_the_config_language() {
        let p = |t: &str| t.parse::<Subnet>();
        assert_eq!(p("1.1"), Ok(Subnet::exact(a(1, 1))));
        assert_eq!(p("192.0/8"), Ok(Subnet::new(a(192, 0), a(255, 0))));
        assert_eq!(p("128.0\\1"), Ok(Subnet::new(a(128, 0), a(0, 128))));
        assert_eq!(p("255.0:128.240"), Ok(Subnet::new(a(255, 0), a(128, 240))));
        assert_eq!(
            p("256.1").map_err(|e| e.0),
            Err("Invalid MAVLink subnet: \"256.1\".".into())
        );
        assert_eq!(
            p("1.1/17").map_err(|e| e.0),
            Err("Forward slash mask (17) is outside of allowed range (0 - 16).".into())
        );
        assert_eq!(
            p("1.1\\9").map_err(|e| e.0),
            Err("Backslash mask (9) is outside of allowed range (0 - 8).".into())
        );
        assert_eq!(
            p("1.1/+3").map_err(|e| e.0),
            Err("Forward slash mask (+3) is outside of allowed range (0 - 16).".into())
        );
        assert!(p("").is_err() && p("1").is_err() && p("1.+1").is_err());
    }
}
