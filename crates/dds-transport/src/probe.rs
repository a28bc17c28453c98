//! What `ulab doctor` needs below Cyclone: the host's network interfaces, and the DDS participants of a domain as
//! they announce themselves in SPDP (RTPS 2.x participant discovery), found by probing.
//!
//! The probe sends one minimal SPDP announcement (a participant with no endpoints: SPDP writer and reader only,
//! lease 5 s, vendor id unknown) to every participant-index port of the domain on each peer address (Cyclone's
//! port mapping, unicast metatraffic: `7400 + 250 d + 10 + 2 i`; the ports Cyclone 0.10.2 uses on loopback, where
//! it sends no multicast) and, on a multicast-capable path, to the domain's SPDP multicast group
//! `239.255.0.1:7400 + 250 d`. Cyclone answers a new participant at once with its own SPDP announcement to the
//! locator it gave: vendor, protocol version, participant GUID, domain, and in Cyclone's vendor-specific parameter
//! `0x8007` its version (`host/0.10.2/Linux/Linux`), plus process name and pid in its property list. The probe
//! never announces endpoints, so no peer starts endpoint discovery with it (nothing a Cyclone 0.10.2 peer could
//! trip over), and it disappears from the peers when its lease runs out.
//!
//! Safety: the caller decides what may be probed; [`ProbeTarget::check`] applies the project's rule (domain 0 or a
//! non-loopback interface only with `allow_robot`). Multicast probes leave through the named interface only
//! (`IP_MULTICAST_IF`), with TTL 1.

use crate::config::is_loopback_interface;
use std::collections::BTreeMap;
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::time::{Duration, Instant};

/// Cyclone's (and the DDSI-RTPS spec's) default port mapping.
const PORT_BASE: u32 = 7400;
const DOMAIN_GAIN: u32 = 250;
const PARTICIPANT_GAIN: u32 = 2;
const UNICAST_METATRAFFIC_OFFSET: u32 = 10;
/// The SPDP multicast group of every DDSI implementation.
pub const SPDP_MULTICAST_GROUP: Ipv4Addr = Ipv4Addr::new(239, 255, 0, 1);

/// Unicast metatraffic (discovery) port of participant index `index` on `domain`.
pub fn unicast_discovery_port(domain: u32, index: u32) -> u32 {
    PORT_BASE + DOMAIN_GAIN * domain + UNICAST_METATRAFFIC_OFFSET + PARTICIPANT_GAIN * index
}

/// Multicast SPDP port of `domain`.
pub fn multicast_discovery_port(domain: u32) -> u32 {
    PORT_BASE + DOMAIN_GAIN * domain
}

/// Errors of the probe.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ProbeError {
    /// The probe would reach a real robot (domain 0 or a non-loopback interface) without
    /// [`ProbeTarget::allow_robot`].
    #[error("refusing {what}: a real robot may be there; pass allow_robot (--allow-robot) to probe it")]
    RobotNotAllowed {
        /// What was refused, e.g. "domain 0".
        what: String,
    },
    /// The named interface does not exist or has no IPv4 address to probe from.
    #[error("interface {0:?} not found or without an IPv4 address")]
    NoInterface(String),
    /// The host's interfaces could not be listed (getifaddrs failed).
    #[error("listing network interfaces: {0}")]
    Interfaces(#[source] nix::Error),
    /// Opening, configuring or using the probe's UDP socket failed.
    #[error("socket: {0}")]
    Socket(#[from] std::io::Error),
    /// A domain id above [`MAX_DOMAIN`](crate::config::MAX_DOMAIN), whose RTPS ports would not fit.
    #[error("domain {domain} has no RTPS ports (highest is 232)")]
    BadDomain {
        /// The domain id asked for.
        domain: u32,
    },
}

/// One network interface of this host.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct NetInterface {
    /// Interface name (`lo`, `eth0`, ...).
    pub name: String,
    /// Whether the interface is up (the kernel's UP flag).
    pub up: bool,
    /// Whether it is a loopback interface (the kernel's LOOPBACK flag).
    pub loopback: bool,
    /// The kernel's MULTICAST flag (Linux's `lo` has none: Cyclone 0.10.2 then sends no multicast on it, Cyclone
    /// 11 uses multicast on a loopback interface anyway).
    pub multicast_flag: bool,
    /// Its IPv4 addresses (possibly none).
    pub ipv4: Vec<Ipv4Addr>,
}

/// The host's interfaces (getifaddrs), sorted by name.
pub fn interfaces() -> Result<Vec<NetInterface>, ProbeError> {
    use nix::net::if_::InterfaceFlags as F;
    let mut by_name: BTreeMap<String, NetInterface> = BTreeMap::new();
    for ifa in nix::ifaddrs::getifaddrs().map_err(ProbeError::Interfaces)? {
        let entry = by_name.entry(ifa.interface_name.clone()).or_insert_with(|| NetInterface {
            name: ifa.interface_name.clone(),
            up: ifa.flags.contains(F::IFF_UP),
            loopback: ifa.flags.contains(F::IFF_LOOPBACK),
            multicast_flag: ifa.flags.contains(F::IFF_MULTICAST),
            ipv4: Vec::new(),
        });
        if let Some(addr) = ifa.address.as_ref().and_then(|a| a.as_sockaddr_in()) {
            entry.ipv4.push(addr.ip());
        }
    }
    Ok(by_name.into_values().collect())
}

/// Where and how far to probe.
#[derive(Debug, Clone)]
pub struct ProbeTarget {
    /// Domains to probe.
    pub domains: Vec<u32>,
    /// Interface to probe through (its first IPv4 address is the probe's source and answer address).
    pub interface: String,
    /// Addresses whose participant-index ports get the unicast probe (on loopback: 127.0.0.1).
    pub peers: Vec<Ipv4Addr>,
    /// Highest participant index probed on each peer.
    pub max_participant_index: u32,
    /// Also announce on the SPDP multicast group (through `interface` only).
    pub multicast: bool,
    /// How long to collect answers (the announcement is repeated every 300 ms meanwhile).
    pub duration: Duration,
    /// Permit domain 0 and a non-loopback interface.
    pub allow_robot: bool,
}

impl ProbeTarget {
    /// Applies the safety rule and the domain range.
    pub fn check(&self) -> Result<(), ProbeError> {
        for &d in &self.domains {
            if d > crate::config::MAX_DOMAIN {
                return Err(ProbeError::BadDomain { domain: d });
            }
            if d == 0 && !self.allow_robot {
                return Err(ProbeError::RobotNotAllowed { what: "domain 0".into() });
            }
        }
        if !self.allow_robot && !is_loopback_interface(&self.interface) {
            return Err(ProbeError::RobotNotAllowed { what: format!("non-loopback interface {:?}", self.interface) });
        }
        Ok(())
    }
}

/// A participant as it announced itself in SPDP.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct AnnouncedParticipant {
    /// Domain whose probe it answered (its own `PID_DOMAIN_ID` when it sends one).
    pub domain: u32,
    /// GUID prefix (12 bytes) in hex: the first 24 hex digits of its endpoints' participant GUID.
    pub guid_prefix: String,
    /// RTPS vendor id, `major.minor` in hex (`01.10` = Eclipse Cyclone DDS).
    pub vendor_id: String,
    /// The vendor's name, where the id is one of the registered ones we know.
    pub vendor: Option<&'static str>,
    /// RTPS protocol version announced (`2.1` for Cyclone 0.10, `2.5` for Cyclone 11).
    pub protocol_version: String,
    /// Product version, where the implementation announces one (Cyclone: `0.10.2`, `11.0.1`).
    pub product_version: Option<String>,
    /// Cyclone's raw version string (`host/version/OS/target`).
    pub version_info: Option<String>,
    /// Process name from the participant's property list (Cyclone: `__ProcessName`).
    pub process: Option<String>,
    /// Process id from the property list (Cyclone: `__Pid`), as text.
    pub pid: Option<String>,
    /// Host name from the property list (Cyclone: `__Hostname`).
    pub hostname: Option<String>,
    /// Metatraffic unicast locators it announced.
    pub metatraffic_unicast: Vec<String>,
    /// Where its answer came from.
    pub source: String,
}

/// A registered RTPS vendor (OMG's DDSI-RTPS vendor id list) by id.
pub fn vendor_name(id: [u8; 2]) -> Option<&'static str> {
    Some(match id {
        [0x01, 0x01] => "RTI Connext DDS",
        [0x01, 0x02] => "ADLINK OpenSplice DDS",
        [0x01, 0x03] => "OCI OpenDDS",
        [0x01, 0x04] => "MilSoft",
        [0x01, 0x05] => "Gallium InterCOM",
        [0x01, 0x06] => "TwinOaks CoreDX",
        [0x01, 0x07] => "Lakota Technical Solutions",
        [0x01, 0x08] => "ICOUP Consulting",
        [0x01, 0x09] => "ETRI Diamond DDS",
        [0x01, 0x0a] => "RTI Connext DDS Micro",
        [0x01, 0x0b] => "ADLINK Vortex Cafe",
        [0x01, 0x0c] => "PrismTech",
        [0x01, 0x0d] => "ADLINK Vortex Lite",
        [0x01, 0x0e] => "Technicolor Qeo",
        [0x01, 0x0f] => "eProsima Fast DDS",
        [0x01, 0x10] => "Eclipse Cyclone DDS",
        [0x01, 0x11] => "GurumNetworks GurumDDS",
        [0x01, 0x12] => "Atostek RustDDS",
        [0x01, 0x13] => "Zhenrong Data Distribution Service",
        [0x01, 0x14] => "S2E Software Systems Dust DDS",
        _ => return None,
    })
}

/// Probes `target` (see the module docs); answers per participant GUID prefix, excluding `ignore` (e.g. the
/// caller's own participants).
pub fn probe(target: &ProbeTarget, ignore: &[[u8; 12]]) -> Result<Vec<AnnouncedParticipant>, ProbeError> {
    target.check()?;
    let iface = interfaces()?
        .into_iter()
        .find(|i| i.name == target.interface)
        .ok_or_else(|| ProbeError::NoInterface(target.interface.clone()))?;
    let local = *iface.ipv4.first().ok_or_else(|| ProbeError::NoInterface(target.interface.clone()))?;
    let prefix = own_guid_prefix();
    // One socket per domain: every answer then belongs to a known domain whatever it announces.
    let mut sockets = Vec::new();
    for &domain in &target.domains {
        let socket = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::DGRAM, Some(socket2::Protocol::UDP))?;
        socket.bind(&SocketAddr::V4(SocketAddrV4::new(local, 0)).into())?;
        if target.multicast {
            socket.set_multicast_if_v4(&local)?;
            socket.set_multicast_ttl_v4(1)?;
            socket.set_multicast_loop_v4(true)?;
        }
        socket.set_read_timeout(Some(Duration::from_millis(20)))?;
        let socket: std::net::UdpSocket = socket.into();
        let port = match socket.local_addr()? {
            SocketAddr::V4(a) => a.port(),
            SocketAddr::V6(a) => a.port(),
        };
        let message = spdp_announcement(prefix, domain, SocketAddrV4::new(local, port));
        sockets.push((domain, socket, message));
    }
    let mut found: BTreeMap<(u32, [u8; 12]), AnnouncedParticipant> = BTreeMap::new();
    let start = Instant::now();
    let mut next_round = start;
    let mut buf = vec![0u8; 65536];
    while start.elapsed() < target.duration {
        if Instant::now() >= next_round {
            next_round += Duration::from_millis(300);
            for (domain, socket, message) in &sockets {
                for peer in &target.peers {
                    for index in 0..=target.max_participant_index {
                        let port = unicast_discovery_port(*domain, index);
                        // Ports above 65535 cannot exist; domains are checked to keep them below.
                        let Ok(port) = u16::try_from(port) else { continue };
                        // A closed port answers ICMP unreachable: the next receive may report it; ignored.
                        let _ = socket.send_to(message, SocketAddrV4::new(*peer, port));
                    }
                }
                if target.multicast {
                    if let Ok(port) = u16::try_from(multicast_discovery_port(*domain)) {
                        let _ = socket.send_to(message, SocketAddrV4::new(SPDP_MULTICAST_GROUP, port));
                    }
                }
            }
        }
        for (domain, socket, _) in &sockets {
            loop {
                match socket.recv_from(&mut buf) {
                    Ok((n, from)) => {
                        for p in parse_spdp(&buf[..n], *domain, from) {
                            let key = guid_key(&p.guid_prefix);
                            if key == prefix || ignore.contains(&key) {
                                continue;
                            }
                            found.insert((p.domain, key), p);
                        }
                    }
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::WouldBlock
                                | std::io::ErrorKind::TimedOut
                                | std::io::ErrorKind::ConnectionRefused
                        ) =>
                    {
                        break
                    }
                    Err(e) => return Err(e.into()),
                }
            }
        }
    }
    Ok(found.into_values().collect())
}

fn guid_key(hex: &str) -> [u8; 12] {
    let mut out = [0u8; 12];
    for (i, o) in out.iter_mut().enumerate() {
        *o = hex.get(2 * i..2 * i + 2).and_then(|h| u8::from_str_radix(h, 16).ok()).unwrap_or(0);
    }
    out
}

/// The first 12 bytes of a participant GUID (what SPDP calls the GUID prefix), as [`AnnouncedParticipant`] holds
/// it in hex.
pub fn guid_prefix_hex(guid: &[u8]) -> String {
    guid.iter().take(12).map(|b| format!("{b:02x}")).collect()
}

/// A GUID prefix unique to this probe: a fixed tag, the process id and the clock.
fn own_guid_prefix() -> [u8; 12] {
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos());
    let mut p = [0u8; 12];
    p[..2].copy_from_slice(b"ul");
    p[2..6].copy_from_slice(&std::process::id().to_be_bytes());
    p[6..12].copy_from_slice(&(nanos as u64).to_be_bytes()[2..]);
    p
}

// RTPS constants (DDSI-RTPS 2.x, 9.3 and 9.6).
const SUBMSG_DATA: u8 = 0x15;
const SPDP_WRITER: [u8; 4] = [0x00, 0x01, 0x00, 0xc2];
const SPDP_READER: [u8; 4] = [0x00, 0x01, 0x00, 0xc7];
const PID_SENTINEL: u16 = 0x0001;
const PID_PARTICIPANT_LEASE_DURATION: u16 = 0x0002;
const PID_DOMAIN_ID: u16 = 0x000f;
const PID_PROTOCOL_VERSION: u16 = 0x0015;
const PID_VENDORID: u16 = 0x0016;
const PID_DEFAULT_UNICAST_LOCATOR: u16 = 0x0031;
const PID_METATRAFFIC_UNICAST_LOCATOR: u16 = 0x0032;
const PID_PARTICIPANT_GUID: u16 = 0x0050;
const PID_BUILTIN_ENDPOINT_SET: u16 = 0x0058;
const PID_PROPERTY_LIST: u16 = 0x0059;
/// Cyclone's (vendor 01.10) participant version info: flags, then a `host/version/OS/target` string.
const PID_CYCLONE_PARTICIPANT_VERSION_INFO: u16 = 0x8007;
const CYCLONE: [u8; 2] = [0x01, 0x10];

fn put_param(out: &mut Vec<u8>, pid: u16, value: &[u8]) {
    let padded = value.len().div_ceil(4) * 4;
    out.extend_from_slice(&pid.to_le_bytes());
    out.extend_from_slice(&(padded as u16).to_le_bytes());
    out.extend_from_slice(value);
    out.resize(out.len() + padded - value.len(), 0);
}

fn locator(addr: SocketAddrV4) -> [u8; 24] {
    let mut l = [0u8; 24];
    l[..4].copy_from_slice(&1i32.to_le_bytes()); // LOCATOR_KIND_UDPv4
    l[4..8].copy_from_slice(&u32::from(addr.port()).to_le_bytes());
    l[20..].copy_from_slice(&addr.ip().octets());
    l
}

/// One RTPS message: header and a DATA(p) from the SPDP writer announcing a participant without endpoints.
fn spdp_announcement(prefix: [u8; 12], domain: u32, answer_to: SocketAddrV4) -> Vec<u8> {
    let mut params = vec![0x00, 0x03, 0x00, 0x00]; // PL_CDR_LE
    put_param(&mut params, PID_PROTOCOL_VERSION, &[2, 1]);
    put_param(&mut params, PID_VENDORID, &[0, 0]); // VENDORID_UNKNOWN: not a registered implementation
    let mut guid = prefix.to_vec();
    guid.extend_from_slice(&[0x00, 0x00, 0x01, 0xc1]); // ENTITYID_PARTICIPANT
    put_param(&mut params, PID_PARTICIPANT_GUID, &guid);
    // SPDP announcer and detector only: no SEDP, so nobody sends us endpoint data.
    put_param(&mut params, PID_BUILTIN_ENDPOINT_SET, &3u32.to_le_bytes());
    put_param(&mut params, PID_METATRAFFIC_UNICAST_LOCATOR, &locator(answer_to));
    put_param(&mut params, PID_DEFAULT_UNICAST_LOCATOR, &locator(answer_to));
    let mut lease = 5i32.to_le_bytes().to_vec();
    lease.extend_from_slice(&0u32.to_le_bytes());
    put_param(&mut params, PID_PARTICIPANT_LEASE_DURATION, &lease);
    put_param(&mut params, PID_DOMAIN_ID, &domain.to_le_bytes());
    params.extend_from_slice(&PID_SENTINEL.to_le_bytes());
    params.extend_from_slice(&0u16.to_le_bytes());

    let mut data = Vec::new();
    data.extend_from_slice(&0u16.to_le_bytes()); // extraFlags
    data.extend_from_slice(&16u16.to_le_bytes()); // octetsToInlineQos
    data.extend_from_slice(&SPDP_READER);
    data.extend_from_slice(&SPDP_WRITER);
    data.extend_from_slice(&0i32.to_le_bytes()); // writerSN high
    data.extend_from_slice(&1u32.to_le_bytes()); // writerSN low
    data.extend_from_slice(&params);

    let mut msg = b"RTPS".to_vec();
    msg.extend_from_slice(&[2, 1, 0, 0]); // protocol 2.1, vendor unknown
    msg.extend_from_slice(&prefix);
    msg.push(SUBMSG_DATA);
    msg.push(0x05); // little-endian, data present
    msg.extend_from_slice(&(data.len() as u16).to_le_bytes());
    msg.extend_from_slice(&data);
    msg
}

/// Every SPDP participant announcement in one RTPS message (none if it is anything else or malformed: the probe
/// reads whatever arrives on its port and must never fail on it).
fn parse_spdp(msg: &[u8], domain: u32, from: SocketAddr) -> Vec<AnnouncedParticipant> {
    let mut out = Vec::new();
    if msg.len() < 20 || &msg[..4] != b"RTPS" {
        return out;
    }
    let protocol = format!("{}.{}", msg[4], msg[5]);
    let vendor = [msg[6], msg[7]];
    let mut pos = 20;
    while pos + 4 <= msg.len() {
        let (id, flags) = (msg[pos], msg[pos + 1]);
        let little = flags & 1 != 0;
        let len = rd16(&msg[pos + 2..pos + 4], little) as usize;
        let body_start = pos + 4;
        // Length 0 on a non-PAD/INFO_TS submessage means "to the end of the message".
        let body_end = if len == 0 { msg.len() } else { (body_start + len).min(msg.len()) };
        if id == SUBMSG_DATA && flags & 0x04 != 0 {
            if let Some(p) = parse_spdp_data(&msg[body_start..body_end], little, flags, domain, vendor, &protocol, from)
            {
                out.push(p);
            }
        }
        if len == 0 {
            break;
        }
        pos = body_start + len;
    }
    out
}

fn rd16(b: &[u8], little: bool) -> u16 {
    let a = [b[0], b[1]];
    if little {
        u16::from_le_bytes(a)
    } else {
        u16::from_be_bytes(a)
    }
}

fn rd32(b: &[u8], little: bool) -> u32 {
    let a = [b[0], b[1], b[2], b[3]];
    if little {
        u32::from_le_bytes(a)
    } else {
        u32::from_be_bytes(a)
    }
}

/// A CDR string (length with NUL, bytes) at the start of `b`.
fn cdr_string(b: &[u8], little: bool) -> Option<(String, usize)> {
    let n = rd32(b.get(..4)?, little) as usize;
    let raw = b.get(4..4 + n)?;
    let text = raw.strip_suffix(&[0]).unwrap_or(raw);
    Some((String::from_utf8_lossy(text).into_owned(), 4 + n.div_ceil(4) * 4))
}

/// Skips a parameter list; returns the offset after its sentinel.
fn skip_parameter_list(b: &[u8], little: bool) -> Option<usize> {
    let mut p = 0;
    while p + 4 <= b.len() {
        let pid = rd16(&b[p..], little);
        let len = rd16(&b[p + 2..], little) as usize;
        p += 4 + len;
        if pid == PID_SENTINEL {
            return Some(p);
        }
    }
    None
}

fn parse_spdp_data(
    body: &[u8],
    little: bool,
    flags: u8,
    domain: u32,
    vendor: [u8; 2],
    protocol: &str,
    from: SocketAddr,
) -> Option<AnnouncedParticipant> {
    let to_inline_qos = rd16(body.get(2..4)?, little) as usize;
    if body.get(8..12)? != SPDP_WRITER {
        return None;
    }
    let mut payload_start = 4 + to_inline_qos;
    if flags & 0x02 != 0 {
        payload_start += skip_parameter_list(body.get(payload_start..)?, little)?;
    }
    let payload = body.get(payload_start..)?;
    let encapsulation = u16::from_be_bytes([*payload.first()?, *payload.get(1)?]);
    let le = match encapsulation {
        0x0003 => true,
        0x0002 => false,
        _ => return None,
    };
    let mut p = AnnouncedParticipant {
        domain,
        guid_prefix: String::new(),
        vendor_id: format!("{:02x}.{:02x}", vendor[0], vendor[1]),
        vendor: vendor_name(vendor),
        protocol_version: protocol.to_owned(),
        product_version: None,
        version_info: None,
        process: None,
        pid: None,
        hostname: None,
        metatraffic_unicast: Vec::new(),
        source: from.to_string(),
    };
    let params = payload.get(4..)?;
    let mut i = 0;
    let mut announced_vendor = vendor;
    while i + 4 <= params.len() {
        let pid = rd16(&params[i..], le);
        let len = rd16(&params[i + 2..], le) as usize;
        let v = params.get(i + 4..i + 4 + len)?;
        i += 4 + len;
        match pid {
            PID_SENTINEL => break,
            PID_PROTOCOL_VERSION if len >= 2 => p.protocol_version = format!("{}.{}", v[0], v[1]),
            PID_VENDORID if len >= 2 => {
                announced_vendor = [v[0], v[1]];
                p.vendor_id = format!("{:02x}.{:02x}", v[0], v[1]);
                p.vendor = vendor_name(announced_vendor);
            }
            PID_PARTICIPANT_GUID if len >= 12 => p.guid_prefix = guid_prefix_hex(v),
            PID_DOMAIN_ID if len >= 4 => p.domain = rd32(v, le),
            // Locator kind 1: UDPv4.
            PID_METATRAFFIC_UNICAST_LOCATOR if len >= 24 && rd32(v, le) == 1 => {
                let port = rd32(&v[4..], le);
                p.metatraffic_unicast.push(format!("{}.{}.{}.{}:{port}", v[20], v[21], v[22], v[23]));
            }
            PID_PROPERTY_LIST if len >= 4 => {
                let count = rd32(v, le) as usize;
                let mut at = 4;
                for _ in 0..count.min(64) {
                    let Some((name, n)) = v.get(at..).and_then(|b| cdr_string(b, le)) else { break };
                    at += n;
                    let Some((value, n)) = v.get(at..).and_then(|b| cdr_string(b, le)) else { break };
                    at += n;
                    match name.as_str() {
                        "__ProcessName" => p.process = Some(value),
                        "__Pid" => p.pid = Some(value),
                        "__Hostname" => p.hostname = Some(value),
                        _ => {}
                    }
                }
            }
            PID_CYCLONE_PARTICIPANT_VERSION_INFO if announced_vendor == CYCLONE && len >= 24 => {
                if let Some((text, _)) = cdr_string(&v[20..], le) {
                    p.product_version = text.split('/').nth(1).map(str::to_owned);
                    p.version_info = Some(text);
                }
            }
            _ => {}
        }
    }
    (!p.guid_prefix.is_empty()).then_some(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn port_mapping_matches_cyclone() {
        // Domain 0: SPDP multicast 7400, participant index 0 unicast 7410, index 1 7412 (Cyclone's documentation).
        assert_eq!(multicast_discovery_port(0), 7400);
        assert_eq!(unicast_discovery_port(0, 0), 7410);
        assert_eq!(unicast_discovery_port(0, 1), 7412);
        assert_eq!(unicast_discovery_port(1, 0), 7660);
    }

    /// Our own announcement parses back (the parser reads what the writer wrote; the peers' answers are checked
    /// against real Cyclone 0.10.2 and 11 participants in the doctor tests).
    #[test]
    fn announcement_round_trips_through_the_parser() {
        let prefix = *b"ul0123456789";
        let msg = spdp_announcement(prefix, 7, SocketAddrV4::new(Ipv4Addr::LOCALHOST, 40000));
        let from = SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::LOCALHOST, 1));
        let got = parse_spdp(&msg, 99, from);
        assert_eq!(got.len(), 1);
        assert_eq!(got[0].guid_prefix, guid_prefix_hex(&prefix));
        assert_eq!(got[0].domain, 7);
        assert_eq!(got[0].metatraffic_unicast, vec!["127.0.0.1:40000".to_owned()]);
        assert_eq!((got[0].vendor_id.as_str(), got[0].vendor), ("00.00", None));
    }

    #[test]
    fn garbage_is_ignored() {
        let from = SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::LOCALHOST, 1));
        let msg = spdp_announcement(*b"ul0123456789", 7, SocketAddrV4::new(Ipv4Addr::LOCALHOST, 40000));
        for cut in 0..msg.len() {
            let _ = parse_spdp(&msg[..cut], 1, from);
        }
        let mut bad = msg.clone();
        for i in 20..bad.len() {
            bad[i] ^= 0xff;
            let _ = parse_spdp(&bad, 1, from);
            bad[i] ^= 0xff;
        }
        assert!(parse_spdp(b"RTPX0000000000000000", 1, from).is_empty());
    }
}
