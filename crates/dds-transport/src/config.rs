//! Domain configuration: which DDS domain and network interface, and how discovery works.
//!
//! Safety rule: a real Unitree robot lives on domain 0 on its wired interface. By default the
//! transport only opens a non-zero domain on a loopback interface; anything else needs
//! [`DomainConfig::allow_robot`].

use crate::error::{Error, Result};

/// Default domain: 1, as the public simulator bridges use, never 0 (the robot's).
pub const DEFAULT_DOMAIN: u32 = 1;
/// Default interface: loopback.
pub const DEFAULT_INTERFACE: &str = "lo";
/// Highest domain id whose RTPS port numbers still fit (7400 + 250 * 232 + ...).
pub const MAX_DOMAIN: u32 = 232;

/// How the participant picks its RTPS participant index (which fixes its unicast ports).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParticipantIndex {
    /// The lowest free index, as Cyclone DDS 0.10 picks it when multicast is off.
    Auto,
    /// A fixed index.
    Fixed(u32),
    /// Cyclone's own default (on loopback, 0.10.2 peers will not find us: for experiments).
    CycloneDefault,
}

/// Configuration of one DDS domain as seen by this process.
///
/// Built with [`DomainConfig::loopback`] / [`DomainConfig::new`] and the builder methods; the fields are private so
/// that every configuration goes through [`DomainConfig::validate`] (run by `Participant::new`), which refuses
/// domain 0 and non-loopback interfaces without [`DomainConfig::allow_robot`]. Read them with the getters.
///
/// Cyclone DDS 0.10.2 (Unitree's SDK and robot) disables multicast on `lo` and then discovers
/// peers only by unicast to the well-known ports of participant indices 0..=9 on the peer
/// addresses. So on loopback we take a participant index ourselves and list 127.0.0.1 as a peer,
/// probing indices up to `max_auto_participant_index`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DomainConfig {
    /// DDS domain id.
    pub(crate) domain: u32,
    /// Network interface name (e.g. `lo`, `eth0`).
    pub(crate) interface: String,
    /// Permit domain 0 or a non-loopback interface.
    pub(crate) allow_robot: bool,
    /// Participant index policy.
    pub(crate) participant_index: ParticipantIndex,
    /// Highest participant index probed / taken with [`ParticipantIndex::Auto`].
    pub(crate) max_auto_participant_index: u32,
    /// Unicast discovery peers (addresses). Defaults to `127.0.0.1` on loopback, none otherwise.
    pub(crate) peers: Vec<String>,
    /// Optional Cyclone tracing: (verbosity, output file), e.g. ("finest", "/tmp/cdds.log").
    pub(crate) tracing: Option<(String, String)>,
    /// Socket receive buffer to request (bytes); `None`: Cyclone's default (asks for 1 MiB).
    pub(crate) socket_receive_buffer: Option<u64>,
    /// Size of one Cyclone receive buffer (`Sizing/ReceiveBufferSize`); `None`: Cyclone's default (1 MiB).
    pub(crate) receive_buffer: Option<u64>,
}

impl Default for DomainConfig {
    fn default() -> Self {
        Self {
            domain: DEFAULT_DOMAIN,
            interface: DEFAULT_INTERFACE.to_owned(),
            allow_robot: false,
            participant_index: ParticipantIndex::Auto,
            max_auto_participant_index: 32,
            peers: vec!["127.0.0.1".to_owned()],
            tracing: None,
            socket_receive_buffer: None,
            receive_buffer: None,
        }
    }
}

impl DomainConfig {
    /// Domain 1 on `lo`.
    pub fn new() -> Self {
        Self::default()
    }

    /// Loopback on the given domain.
    pub fn loopback(domain: u32) -> Self {
        Self { domain, ..Self::default() }
    }

    /// Sets the domain id.
    #[must_use]
    pub fn domain(mut self, domain: u32) -> Self {
        self.domain = domain;
        self
    }

    /// Sets the network interface. A non-loopback interface also needs `allow_robot(true)`;
    /// the loopback peer list is dropped for it (set peers explicitly if needed).
    #[must_use]
    pub fn interface(mut self, name: impl Into<String>) -> Self {
        self.interface = name.into();
        if !is_loopback_interface(&self.interface) {
            self.peers.retain(|p| p != "127.0.0.1");
        }
        self
    }

    /// Permits domain 0 and non-loopback interfaces (a real robot may be reached).
    #[must_use]
    pub fn allow_robot(mut self, allow: bool) -> Self {
        self.allow_robot = allow;
        self
    }

    /// Sets the participant index policy.
    #[must_use]
    pub fn participant_index(mut self, index: ParticipantIndex) -> Self {
        self.participant_index = index;
        self
    }

    /// Replaces the unicast discovery peers.
    #[must_use]
    pub fn peers<I, S>(mut self, peers: I) -> Self
    where
        I: IntoIterator<Item = S>,
        S: Into<String>,
    {
        self.peers = peers.into_iter().map(Into::into).collect();
        self
    }

    /// Enables Cyclone's own trace (verbosity e.g. `config`, `fine`, `finest`) into a file.
    #[must_use]
    pub fn tracing(mut self, verbosity: impl Into<String>, file: impl Into<String>) -> Self {
        self.tracing = Some((verbosity.into(), file.into()));
        self
    }

    /// DDS domain id.
    pub fn domain_id(&self) -> u32 {
        self.domain
    }

    /// Network interface name.
    pub fn interface_name(&self) -> &str {
        &self.interface
    }

    /// Whether domain 0 and non-loopback interfaces are permitted.
    pub fn robot_allowed(&self) -> bool {
        self.allow_robot
    }

    /// Participant index policy.
    pub fn participant_index_policy(&self) -> ParticipantIndex {
        self.participant_index
    }

    /// Unicast discovery peers.
    pub fn peer_addresses(&self) -> &[String] {
        &self.peers
    }

    /// Requests a socket receive buffer of `bytes` (Cyclone's `Internal/SocketReceiveBufferSize[@max]`; the
    /// kernel caps it at `net.core.rmem_max`, and whatever it grants is accepted). Why: while a process is
    /// descheduled its samples wait in this buffer; Cyclone's default 1 MiB holds about one second of hg
    /// LowState at 500 Hz, and a longer stall loses samples (best effort).
    pub fn socket_receive_buffer(mut self, bytes: u64) -> Self {
        self.socket_receive_buffer = Some(bytes);
        self
    }

    /// Sets the size of one Cyclone receive buffer (`Sizing/ReceiveBufferSize`, default 1 MiB; Cyclone raises it to
    /// `ReceiveBufferChunkSize` (128 KiB) plus a header if smaller). Why: Cyclone's receive thread writes every
    /// incoming packet at the next free address of its current buffer (a bump allocator) and only replaces the
    /// buffer when it is full, so a long-running process that receives little (a bridge that only sees discovery
    /// traffic) touches a fresh page every few KiB received: its anonymous RSS creeps up by the bytes received until
    /// a full buffer (about 1 MiB) is resident, and a new buffer may land in untouched memory again. A small buffer
    /// bounds that creep to a few hundred KiB within minutes.
    #[must_use]
    pub fn receive_buffer_size(mut self, bytes: u64) -> Self {
        self.receive_buffer = Some(bytes);
        self
    }

    /// The Cyclone receive buffer size requested, if any.
    pub fn receive_buffer_size_bytes(&self) -> Option<u64> {
        self.receive_buffer
    }

    /// The socket receive buffer requested, if any.
    pub fn socket_receive_buffer_bytes(&self) -> Option<u64> {
        self.socket_receive_buffer
    }

    /// Whether this configuration may reach a real robot: domain 0 or a non-loopback interface.
    pub fn may_reach_robot(&self) -> bool {
        self.domain == unitree_idl::topics::ROBOT_DOMAIN || !is_loopback_interface(&self.interface)
    }

    /// Checks the safety rule and the values.
    pub fn validate(&self) -> Result<()> {
        if self.domain > MAX_DOMAIN {
            return Err(Error::InvalidConfig(format!("domain {} is above {MAX_DOMAIN}", self.domain)));
        }
        if !is_plain_token(&self.interface) {
            return Err(Error::InvalidConfig(format!("interface name {:?}", self.interface)));
        }
        for p in &self.peers {
            if !is_plain_token(p) {
                return Err(Error::InvalidConfig(format!("peer address {p:?}")));
            }
        }
        if let Some((verbosity, file)) = &self.tracing {
            if !is_plain_token(verbosity) || file.is_empty() || file.contains(['<', '>', '&', '"', '\'']) {
                return Err(Error::InvalidConfig("tracing settings".to_owned()));
            }
        }
        if let ParticipantIndex::Fixed(i) = self.participant_index {
            if i > 119 {
                return Err(Error::InvalidConfig(format!("participant index {i} is above 119")));
            }
        }
        if let Some(b) = self.socket_receive_buffer {
            if !(64 * 1024..=1 << 30).contains(&b) {
                return Err(Error::InvalidConfig(format!("socket receive buffer {b} bytes (64 KiB to 1 GiB)")));
            }
        }
        if let Some(b) = self.receive_buffer {
            if !(64 * 1024..=64 << 20).contains(&b) {
                return Err(Error::InvalidConfig(format!("receive buffer {b} bytes (64 KiB to 64 MiB)")));
            }
        }
        if self.max_auto_participant_index > 119 {
            return Err(Error::InvalidConfig("max_auto_participant_index above 119".to_owned()));
        }
        if !self.allow_robot {
            if self.domain == 0 {
                return Err(Error::RobotNotAllowed { what: "domain 0".to_owned() });
            }
            if !is_loopback_interface(&self.interface) {
                return Err(Error::RobotNotAllowed { what: format!("non-loopback interface {:?}", self.interface) });
            }
        }
        Ok(())
    }

    /// The Cyclone DDS XML configuration for this domain.
    pub fn to_xml(&self) -> String {
        let index = match self.participant_index {
            ParticipantIndex::Auto => "auto".to_owned(),
            ParticipantIndex::Fixed(i) => i.to_string(),
            ParticipantIndex::CycloneDefault => "default".to_owned(),
        };
        let mut peers = String::new();
        for p in &self.peers {
            peers.push_str(&format!("<Peer address=\"{p}\"/>"));
        }
        let peers = if peers.is_empty() { String::new() } else { format!("<Peers>{peers}</Peers>") };
        let internal = match self.socket_receive_buffer {
            Some(b) => format!("<Internal><SocketReceiveBufferSize max=\"{b}B\"/></Internal>"),
            None => String::new(),
        };
        let sizing = match self.receive_buffer {
            Some(b) => format!("<Sizing><ReceiveBufferSize>{b}B</ReceiveBufferSize></Sizing>"),
            None => String::new(),
        };
        let tracing = match &self.tracing {
            Some((v, f)) => format!("<Tracing><Verbosity>{v}</Verbosity><OutputFile>{f}</OutputFile></Tracing>"),
            None => String::new(),
        };
        format!(
            "<CycloneDDS><Domain Id=\"any\">\
             <General><Interfaces><NetworkInterface name=\"{iface}\" priority=\"default\" multicast=\"default\"/></Interfaces></General>\
             <Discovery><ParticipantIndex>{index}</ParticipantIndex>\
             <MaxAutoParticipantIndex>{max}</MaxAutoParticipantIndex>{peers}</Discovery>\
             {internal}{sizing}{tracing}</Domain></CycloneDDS>",
            iface = self.interface,
            max = self.max_auto_participant_index,
        )
    }
}

/// Letters, digits and `.-_:`: enough for interface names and IP addresses, nothing that could
/// break out of an XML attribute.
fn is_plain_token(s: &str) -> bool {
    !s.is_empty() && s.len() <= 255 && s.chars().all(|c| c.is_ascii_alphanumeric() || "._-:".contains(c))
}

/// Whether the named interface is a loopback interface: Linux's IFF_LOOPBACK flag when sysfs
/// has it, otherwise the conventional names.
pub fn is_loopback_interface(name: &str) -> bool {
    const IFF_LOOPBACK: u32 = 0x8;
    if !is_plain_token(name) || name.contains('/') || name == "." || name == ".." {
        return false;
    }
    let path = format!("/sys/class/net/{name}/flags");
    if let Ok(text) = std::fs::read_to_string(path) {
        let t = text.trim().trim_start_matches("0x");
        if let Ok(flags) = u32::from_str_radix(t, 16) {
            return flags & IFF_LOOPBACK != 0;
        }
    }
    name == "lo" || name == "lo0"
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_safe() {
        let c = DomainConfig::default();
        assert_eq!(c.domain, 1);
        assert_eq!(c.interface, "lo");
        assert!(c.validate().is_ok());
    }

    #[test]
    fn robot_settings_need_the_flag() {
        assert!(matches!(DomainConfig::loopback(0).validate(), Err(Error::RobotNotAllowed { .. })));
        assert!(DomainConfig::loopback(0).allow_robot(true).validate().is_ok());
        let eth = DomainConfig::new().interface("eth0");
        assert!(matches!(eth.validate(), Err(Error::RobotNotAllowed { .. })));
        assert!(eth.clone().allow_robot(true).validate().is_ok());
        assert!(eth.peers.is_empty());
    }

    #[test]
    fn rejects_injection_and_ranges() {
        assert!(DomainConfig::new().interface("lo\"/><x").allow_robot(true).validate().is_err());
        assert!(DomainConfig::new().peers(["1.2.3.4<"]).validate().is_err());
        assert!(DomainConfig::loopback(233).validate().is_err());
        assert!(DomainConfig::new().participant_index(ParticipantIndex::Fixed(120)).validate().is_err());
    }

    #[test]
    fn socket_buffer_is_bounded_and_in_the_xml() {
        assert!(!DomainConfig::loopback(7).to_xml().contains("SocketReceiveBufferSize"));
        let c = DomainConfig::loopback(7).socket_receive_buffer(8 << 20);
        assert!(c.validate().is_ok());
        assert!(c.to_xml().contains("<Internal><SocketReceiveBufferSize max=\"8388608B\"/></Internal>"));
        assert!(DomainConfig::loopback(7).socket_receive_buffer(1000).validate().is_err());
        assert!(DomainConfig::loopback(7).socket_receive_buffer(2 << 30).validate().is_err());
    }

    #[test]
    fn receive_buffer_is_bounded_and_in_the_xml() {
        assert!(!DomainConfig::loopback(7).to_xml().contains("ReceiveBufferSize"));
        let c = DomainConfig::loopback(7).receive_buffer_size(256 * 1024);
        assert!(c.validate().is_ok());
        assert!(c.to_xml().contains("<Sizing><ReceiveBufferSize>262144B</ReceiveBufferSize></Sizing>"));
        assert!(DomainConfig::loopback(7).receive_buffer_size(1000).validate().is_err());
    }

    #[test]
    fn xml_has_discovery_settings() {
        let x = DomainConfig::loopback(7).to_xml();
        assert!(x.contains("<NetworkInterface name=\"lo\""));
        assert!(x.contains("<ParticipantIndex>auto</ParticipantIndex>"));
        assert!(x.contains("<Peer address=\"127.0.0.1\"/>"));
    }
}
