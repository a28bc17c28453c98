//! The peer's RTPS vendor and protocol version as seen on the wire.
//!
//! DDS implementations answer a new participant's SPDP announcement with their own, sent straight to the new
//! participant's metatraffic locator. We announce a minimal participant of our own (one SPDP DATA, nothing else)
//! whose locator is a plain UDP socket, and read the 20-byte RTPS header of every answer: protocol version, vendor
//! id, GUID prefix (OMG DDSI-RTPS 2.x, 8.3.3). The announcement goes where SPDP is listened for on loopback: the
//! multicast group 239.255.0.1 on the domain's discovery port and the unicast discovery ports of participant indices
//! 0 to [`MAX_INDEX`]. Loopback only: on another interface the answer would need that interface's address, and the
//! run may face a robot.

use std::collections::BTreeMap;
use std::net::{Ipv4Addr, SocketAddrV4, UdpSocket};
use std::time::{Duration, Instant};

/// Highest participant index whose unicast discovery port gets the announcement (ours use up to 32, Cyclone's
/// default is 9).
pub const MAX_INDEX: u16 = 40;
/// RTPS port mapping (DDSI-RTPS 9.6.1.1): PB, DG, PG, d0 (multicast discovery), d1 (unicast discovery).
const PB: u32 = 7400;
const DG: u32 = 250;
const PG: u32 = 2;
const D0: u32 = 0;
const D1: u32 = 10;
const SPDP_GROUP: Ipv4Addr = Ipv4Addr::new(239, 255, 0, 1);

/// One participant as it answered.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WireParticipant {
    pub guid_prefix: [u8; 12],
    pub protocol: (u8, u8),
    pub vendor: [u8; 2],
}

impl WireParticipant {
    /// `2.1`.
    pub fn protocol_text(&self) -> String {
        format!("{}.{}", self.protocol.0, self.protocol.1)
    }

    /// `1.16 Eclipse Cyclone DDS`.
    pub fn vendor_text(&self) -> String {
        let [a, b] = self.vendor;
        match vendor_name(self.vendor) {
            Some(n) => format!("{a}.{b} {n}"),
            None => format!("{a}.{b}"),
        }
    }
}

/// Vendor ids assigned by the OMG (as Wireshark's RTPS dissector lists them).
pub fn vendor_name(id: [u8; 2]) -> Option<&'static str> {
    Some(match u16::from_be_bytes(id) {
        0x0101 => "RTI Connext DDS",
        0x0102 => "ADLINK OpenSplice DDS",
        0x0103 => "OCI OpenDDS",
        0x0104 => "MilSoft",
        0x0105 => "Kongsberg InterCOM DDS",
        0x0106 => "TwinOaks CoreDX DDS",
        0x0107 => "Lakota Technical Solutions",
        0x0108 => "ICOUP Consulting",
        0x0109 => "ETRI Diamond DDS",
        0x010A => "RTI Connext DDS Micro",
        0x010B => "ADLINK Vortex Cafe",
        0x010C => "PrismTech",
        0x010D => "ADLINK Vortex Lite",
        0x010E => "Technicolor Qeo",
        0x010F => "eProsima Fast DDS",
        0x0110 => "Eclipse Cyclone DDS",
        0x0111 => "GurumNetworks GurumDDS",
        _ => return None,
    })
}

/// Parses the RTPS header of a datagram.
pub fn parse_header(datagram: &[u8]) -> Option<WireParticipant> {
    if datagram.len() < 20 || &datagram[..4] != b"RTPS" {
        return None;
    }
    let mut guid_prefix = [0u8; 12];
    guid_prefix.copy_from_slice(&datagram[8..20]);
    Some(WireParticipant { guid_prefix, protocol: (datagram[4], datagram[5]), vendor: [datagram[6], datagram[7]] })
}

fn param(out: &mut Vec<u8>, pid: u16, value: &[u8]) {
    out.extend_from_slice(&pid.to_le_bytes());
    let padded = value.len().div_ceil(4) * 4;
    out.extend_from_slice(&u16::try_from(padded).unwrap_or(0).to_le_bytes());
    out.extend_from_slice(value);
    out.resize(out.len() + padded - value.len(), 0);
}

fn locator(port: u16) -> [u8; 24] {
    let mut l = [0u8; 24];
    l[..4].copy_from_slice(&1i32.to_le_bytes()); // LOCATOR_KIND_UDPv4
    l[4..8].copy_from_slice(&u32::from(port).to_le_bytes());
    l[20..24].copy_from_slice(&Ipv4Addr::LOCALHOST.octets());
    l
}

/// An SPDP DATA announcing participant `prefix` on `domain`, reachable at 127.0.0.1:`port`, leased for `lease_s`.
pub fn spdp_announcement(prefix: [u8; 12], domain: u32, port: u16, lease_s: i32) -> Vec<u8> {
    let mut payload = vec![0x00, 0x03, 0x00, 0x00]; // PL_CDR_LE
    param(&mut payload, 0x0015, &[2, 1]); // PID_PROTOCOL_VERSION
    param(&mut payload, 0x0016, &[0, 0]); // PID_VENDORID: unknown (we are no DDS implementation)
    let mut guid = prefix.to_vec();
    guid.extend_from_slice(&[0x00, 0x00, 0x01, 0xc1]); // ENTITYID_PARTICIPANT
    param(&mut payload, 0x0050, &guid); // PID_PARTICIPANT_GUID
    param(&mut payload, 0x000f, &domain.to_le_bytes()); // PID_DOMAIN_ID
    param(&mut payload, 0x0058, &3u32.to_le_bytes()); // PID_BUILTIN_ENDPOINT_SET: participant announcer + detector
    param(&mut payload, 0x0032, &locator(port)); // PID_METATRAFFIC_UNICAST_LOCATOR
    param(&mut payload, 0x0031, &locator(port)); // PID_DEFAULT_UNICAST_LOCATOR
    let mut lease = lease_s.to_le_bytes().to_vec();
    lease.extend_from_slice(&0u32.to_le_bytes());
    param(&mut payload, 0x0002, &lease); // PID_PARTICIPANT_LEASE_DURATION
    payload.extend_from_slice(&[0x01, 0x00, 0x00, 0x00]); // PID_SENTINEL

    let mut data = Vec::new();
    data.extend_from_slice(&0u16.to_le_bytes()); // extraFlags
    data.extend_from_slice(&16u16.to_le_bytes()); // octetsToInlineQos
    data.extend_from_slice(&[0x00, 0x01, 0x00, 0xc7]); // readerId: SPDP builtin participant reader
    data.extend_from_slice(&[0x00, 0x01, 0x00, 0xc2]); // writerId: SPDP builtin participant writer
    data.extend_from_slice(&0i32.to_le_bytes()); // writerSN high
    data.extend_from_slice(&1u32.to_le_bytes()); // writerSN low
    data.extend_from_slice(&payload);

    let mut msg = b"RTPS".to_vec();
    msg.extend_from_slice(&[2, 1, 0, 0]); // protocol 2.1, vendor unknown
    msg.extend_from_slice(&prefix);
    msg.push(0x15); // DATA
    msg.push(0x05); // little endian, data present
    msg.extend_from_slice(&u16::try_from(data.len()).unwrap_or(0).to_le_bytes());
    msg.extend_from_slice(&data);
    msg
}

/// Announces a participant on `domain` over loopback and collects, for up to `wait`, the RTPS header of every
/// participant that answers (by GUID prefix).
pub fn answering_participants(domain: u32, wait: Duration) -> std::io::Result<BTreeMap<[u8; 12], WireParticipant>> {
    let socket = UdpSocket::bind(SocketAddrV4::new(Ipv4Addr::LOCALHOST, 0))?;
    let port = socket.local_addr()?.port();
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos());
    let mut prefix = [0u8; 12];
    prefix[..4].copy_from_slice(b"ulab");
    prefix[4..8].copy_from_slice(&std::process::id().to_le_bytes());
    prefix[8..].copy_from_slice(&(nanos as u32).to_le_bytes());
    let msg = spdp_announcement(prefix, domain, port, 5);
    let base = PB + DG * domain;
    let send_all = |s: &UdpSocket| -> std::io::Result<()> {
        for i in 0..=u32::from(MAX_INDEX) {
            if let Ok(p) = u16::try_from(base + D1 + PG * i) {
                // A closed port answers with an ICMP error the next receive may report: ignore both.
                let _ = s.send_to(&msg, SocketAddrV4::new(Ipv4Addr::LOCALHOST, p));
            }
        }
        if let Ok(p) = u16::try_from(base + D0) {
            let mc = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::DGRAM, Some(socket2::Protocol::UDP))?;
            mc.set_multicast_if_v4(&Ipv4Addr::LOCALHOST)?;
            mc.set_multicast_loop_v4(true)?;
            let _ = mc.send_to(&msg, &SocketAddrV4::new(SPDP_GROUP, p).into());
        }
        Ok(())
    };
    send_all(&socket)?;
    let mut seen = BTreeMap::new();
    let end = Instant::now() + wait;
    let mut buf = vec![0u8; 65536];
    let mut resent = false;
    while let Some(left) = end.checked_duration_since(Instant::now()) {
        if !resent && left < wait / 2 {
            // Once more, in case the first went out before a peer listened.
            send_all(&socket)?;
            resent = true;
        }
        socket.set_read_timeout(Some(left.clamp(Duration::from_millis(1), Duration::from_millis(100))))?;
        match socket.recv_from(&mut buf) {
            Ok((n, _)) => {
                if let Some(p) = parse_header(&buf[..n]) {
                    seen.entry(p.guid_prefix).or_insert(p);
                }
            }
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => {}
            Err(e) => return Err(e),
        }
    }
    seen.remove(&prefix);
    Ok(seen)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn announcement_has_a_valid_header_and_aligned_parameters() {
        let m = spdp_announcement([7; 12], 123, 40000, 5);
        let p = parse_header(&m).expect("header");
        assert_eq!((p.protocol, p.vendor, p.guid_prefix), ((2, 1), [0, 0], [7; 12]));
        // Submessage length covers the rest of the datagram; the parameter list ends with a sentinel.
        let len = u16::from_le_bytes([m[22], m[23]]) as usize;
        assert_eq!(20 + 4 + len, m.len());
        assert_eq!(&m[m.len() - 4..], &[1, 0, 0, 0]);
        assert_eq!(len % 4, 0);
    }

    #[test]
    fn vendor_names() {
        let p = WireParticipant { guid_prefix: [0; 12], protocol: (2, 5), vendor: [1, 16] };
        assert_eq!(p.vendor_text(), "1.16 Eclipse Cyclone DDS");
        assert_eq!(p.protocol_text(), "2.5");
        assert_eq!(vendor_name([1, 0x0f]), Some("eProsima Fast DDS"));
        assert_eq!(vendor_name([9, 9]), None);
        assert!(parse_header(b"RTPX....").is_none());
    }
}
