//! Link-layer frames from packet captures down to their UDP payload: Ethernet (with
//! VLAN tags), Linux cooked v1/v2, BSD loopback (DLT_NULL) and raw IPv4.

/// `DLT_NULL`: BSD loopback, a 4-byte address family in host order.
pub(crate) const DLT_NULL: u32 = 0;
/// `DLT_EN10MB`: Ethernet.
pub(crate) const DLT_EN10MB: u32 = 1;
/// `DLT_RAW`: raw IP.
pub(crate) const DLT_RAW: u32 = 101;
/// `DLT_LINUX_SLL`: Linux cooked capture v1.
pub(crate) const DLT_LINUX_SLL: u32 = 113;
/// `DLT_IPV4`: raw IPv4.
pub(crate) const DLT_IPV4: u32 = 228;
/// `DLT_LINUX_SLL2`: Linux cooked capture v2 (`tshark -i any`).
pub(crate) const DLT_LINUX_SLL2: u32 = 276;

/// True for the link types [`udp_payload`] understands.
pub(crate) fn supported(link_type: u32) -> bool {
    matches!(
        link_type,
        DLT_NULL | DLT_EN10MB | DLT_RAW | DLT_LINUX_SLL | DLT_IPV4 | DLT_LINUX_SLL2
    )
}

/// A UDP datagram found inside a captured frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Udp<'a> {
    /// Source IPv4 address and port.
    pub source: ([u8; 4], u16),
    /// Destination IPv4 address and port.
    pub destination: ([u8; 4], u16),
    /// The UDP payload.
    pub payload: &'a [u8],
    /// Offset of the payload within the captured frame.
    pub offset: usize,
}

fn be16(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_be_bytes([*b.get(at)?, *b.get(at + 1)?]))
}

/// Offset of the IPv4 header within a frame of `link_type`, if the frame carries IPv4.
fn ipv4_start(link_type: u32, frame: &[u8]) -> Option<usize> {
    match link_type {
        DLT_NULL => {
            let fam: [u8; 4] = frame.get(..4)?.try_into().ok()?;
            (u32::from_le_bytes(fam) == 2 || u32::from_be_bytes(fam) == 2).then_some(4)
        }
        DLT_EN10MB => {
            let mut at = 12;
            let mut ethertype = be16(frame, at)?;
            while ethertype == 0x8100 || ethertype == 0x88a8 {
                at += 4;
                ethertype = be16(frame, at)?;
            }
            (ethertype == 0x0800).then_some(at + 2)
        }
        DLT_LINUX_SLL => (be16(frame, 14)? == 0x0800).then_some(16),
        DLT_LINUX_SLL2 => (be16(frame, 0)? == 0x0800).then_some(20),
        DLT_RAW | DLT_IPV4 => Some(0),
        _ => None,
    }
}

/// The UDP datagram carried by `frame`, if it is an unfragmented IPv4/UDP packet.
pub(crate) fn udp_payload(link_type: u32, frame: &[u8]) -> Option<Udp<'_>> {
    let ip_at = ipv4_start(link_type, frame)?;
    let ip = frame.get(ip_at..)?;
    let first = *ip.first()?;
    if first >> 4 != 4 {
        return None;
    }
    let ihl = (first & 0x0f) as usize * 4;
    let total = be16(ip, 2)? as usize;
    let fragment = be16(ip, 6)?;
    if *ip.get(9)? != 17 || ihl < 20 || fragment & 0x3fff != 0 {
        return None;
    }
    let src: [u8; 4] = ip.get(12..16)?.try_into().ok()?;
    let dst: [u8; 4] = ip.get(16..20)?.try_into().ok()?;
    let udp = ip.get(ihl..total.min(ip.len()))?;
    let udp_len = be16(udp, 4)? as usize;
    if udp_len < 8 {
        return None;
    }
    Some(Udp {
        source: (src, be16(udp, 0)?),
        destination: (dst, be16(udp, 2)?),
        payload: udp.get(8..udp_len)?,
        offset: ip_at + ihl + 8,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// IPv4 + UDP 127.0.0.1:1000 -> 127.0.0.2:2000 carrying `payload`.
    fn ip_udp(payload: &[u8]) -> Vec<u8> {
        let total = 20 + 8 + payload.len();
        let mut p = vec![
            0x45,
            0,
            (total >> 8) as u8,
            total as u8,
            0,
            0,
            0x40,
            0,
            64,
            17,
            0,
            0,
        ];
        p.extend([127, 0, 0, 1, 127, 0, 0, 2]);
        let ulen = 8 + payload.len();
        p.extend([0x03, 0xe8, 0x07, 0xd0, (ulen >> 8) as u8, ulen as u8, 0, 0]);
        p.extend(payload);
        p
    }

    #[test]
    fn every_link_type_reaches_the_payload() {
        let ip = ip_udp(b"mav");
        let mut eth = vec![0u8; 12];
        eth.extend([0x81, 0x00, 0, 1, 0x08, 0x00]); // one VLAN tag
        eth.extend(&ip);
        let mut null = 2u32.to_le_bytes().to_vec();
        null.extend(&ip);
        let mut sll = vec![0u8; 14];
        sll.extend([0x08, 0x00]);
        sll.extend(&ip);
        let mut sll2 = vec![0x08, 0x00];
        sll2.extend([0u8; 18]);
        sll2.extend(&ip);
        for (lt, frame) in [
            (DLT_EN10MB, eth),
            (DLT_NULL, null),
            (DLT_LINUX_SLL, sll),
            (DLT_LINUX_SLL2, sll2),
            (DLT_RAW, ip),
        ] {
            let udp = udp_payload(lt, &frame).unwrap_or_else(|| panic!("link type {lt}"));
            assert_eq!(udp.payload, b"mav");
            assert_eq!(udp.source, ([127, 0, 0, 1], 1000));
            assert_eq!(udp.destination, ([127, 0, 0, 2], 2000));
            assert_eq!(&frame[udp.offset..], b"mav");
        }
    }

    #[test]
    fn non_udp_and_fragments_are_passed_over() {
        let mut tcp = ip_udp(b"x");
        tcp[9] = 6;
        assert!(udp_payload(DLT_RAW, &tcp).is_none());
        let mut frag = ip_udp(b"x");
        frag[6] = 0x20; // more fragments
        assert!(udp_payload(DLT_RAW, &frag).is_none());
        assert!(udp_payload(DLT_RAW, &[0x45]).is_none());
        assert!(udp_payload(DLT_EN10MB, &[0; 14]).is_none());
    }
}
