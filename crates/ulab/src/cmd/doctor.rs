//! `ulab doctor`: for a user whose SDK client sees nothing. Lists the interfaces and whether they carry multicast,
//! the DDS participants of the domain (found by probing both the SPDP multicast group and the unicast
//! participant-index ports Cyclone 0.10.2 uses on loopback) with their vendor, protocol and product version as
//! they announce them, their topics, type names, QoS and whether each endpoint carries XTypes type information;
//! then says in plain words what is wrong and how to fix it.
//!
//! Participants come from `dds_transport::probe` (raw SPDP); endpoints from a Cyclone participant of our transport
//! (which announces no endpoints and no type information, so it is safe next to Cyclone 0.10.2 peers).
//! Exit code: 0 no problem found (warnings allowed), 1 at least one problem, 2 the doctor itself failed.

use crate::exit::Exit;
use anyhow::{Context, Result};
use dds_transport::probe::{self, AnnouncedParticipant, NetInterface, ProbeTarget};
use dds_transport::{DiscoveredEndpoint, DomainConfig, Durability, EndpointKind, Participant, Reliability};
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet};
use std::net::Ipv4Addr;
use std::time::{Duration, Instant};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// DDS domain the client uses.
    #[arg(long, default_value_t = dds_transport::config::DEFAULT_DOMAIN)]
    pub domain: u32,
    /// Network interface the client uses (anything but loopback needs --allow-robot).
    #[arg(long, default_value = dds_transport::config::DEFAULT_INTERFACE)]
    pub interface: String,
    /// Permit domain 0 and non-loopback interfaces, where a real robot may be (also scans domain 0).
    #[arg(long)]
    pub allow_robot: bool,
    /// Other domains to look on, for a participant the client should have seen: a list like `0,1,100-110`
    /// (default: 1, and 0 with --allow-robot).
    #[arg(long, value_parser = parse_domains)]
    pub scan_domains: Option<Domains>,
    /// Seconds to listen for answers and endpoints.
    #[arg(long, default_value_t = 3.0)]
    pub seconds: f64,
    /// Highest participant index probed on each peer address.
    #[arg(long, default_value_t = 32)]
    pub max_participant_index: u32,
    /// Output: text or json.
    #[arg(long, value_enum, default_value_t = super::OutputFormat::Text)]
    pub format: super::OutputFormat,
}

/// A list of domain ids.
#[derive(Debug, Clone)]
pub struct Domains(pub Vec<u32>);

fn parse_domains(s: &str) -> Result<Domains, String> {
    let mut out = BTreeSet::new();
    for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (a, b) = part.split_once('-').unwrap_or((part, part));
        let (a, b): (u32, u32) = (
            a.trim().parse().map_err(|_| format!("bad domain `{a}`"))?,
            b.trim().parse().map_err(|_| format!("bad domain `{b}`"))?,
        );
        if a > b || b > dds_transport::config::MAX_DOMAIN {
            return Err(format!("bad domain range `{part}` (0..=232)"));
        }
        out.extend(a..=b);
    }
    Ok(Domains(out.into_iter().collect()))
}

/// How bad a finding is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    Problem,
    Warning,
    Info,
}

/// One diagnosis: a stable code, and what is wrong with the fix, in plain words.
#[derive(Debug, Clone, Serialize)]
pub struct Finding {
    pub code: &'static str,
    pub severity: Severity,
    pub message: String,
}

/// An endpoint as the report shows it.
#[derive(Debug, Clone, Serialize)]
pub struct EndpointReport {
    pub kind: &'static str,
    pub topic: String,
    pub type_name: String,
    pub reliability: Option<&'static str>,
    pub durability: Option<&'static str>,
    /// KEEP_LAST depth, -1 for KEEP_ALL.
    pub history: Option<i32>,
    pub type_information: bool,
}

/// A participant with its endpoints.
#[derive(Debug, Clone, Serialize)]
pub struct ParticipantReport {
    #[serde(flatten)]
    pub announced: AnnouncedParticipant,
    pub endpoints: Vec<EndpointReport>,
}

/// The whole report (`--format json`).
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub domain: u32,
    pub interface: String,
    pub interfaces: Vec<NetInterface>,
    pub participants: Vec<ParticipantReport>,
    /// Participants found on the other scanned domains, by domain.
    pub other_domains: BTreeMap<u32, Vec<ParticipantReport>>,
    pub scanned_domains: Vec<u32>,
    pub findings: Vec<Finding>,
}

pub fn run(args: Args) -> Result<Exit> {
    anyhow::ensure!(args.seconds.is_finite() && args.seconds > 0.0, "--seconds must be positive");
    anyhow::ensure!(args.max_participant_index <= 119, "--max-participant-index is at most 119");
    let report = diagnose(&args)?;
    let problems = report.findings.iter().any(|f| f.severity == Severity::Problem);
    if args.format == super::OutputFormat::Json {
        println!("{}", serde_json::to_string_pretty(&report).context("writing the report")?);
    } else {
        print!("{}", text(&report));
    }
    Ok(Exit::failed_if(problems))
}

fn diagnose(args: &Args) -> Result<Report> {
    let interfaces = probe::interfaces().context("listing network interfaces")?;
    let mut findings = Vec::new();
    let cfg = DomainConfig::loopback(args.domain).interface(args.interface.clone()).allow_robot(args.allow_robot);
    cfg.validate()
        .map_err(anyhow::Error::new)
        .context("network settings refused (pass --allow-robot to reach a real robot)")?;
    let Some(iface) = interfaces.iter().find(|i| i.name == args.interface).cloned() else {
        let names: Vec<_> = interfaces.iter().map(|i| i.name.as_str()).collect();
        anyhow::bail!("interface `{}` does not exist here; interfaces: {}", args.interface, names.join(", "));
    };
    if !iface.up || iface.ipv4.is_empty() {
        anyhow::bail!(
            "interface `{}` is {}: DDS cannot use it; bring it up / give it an IPv4 address, or pick another",
            iface.name,
            if iface.up { "up but has no IPv4 address" } else { "down" }
        );
    }
    if !iface.multicast_flag {
        findings.push(Finding {
            code: "no-multicast",
            severity: Severity::Warning,
            message: format!(
                "interface {} is not multicast-capable (no MULTICAST flag): Cyclone DDS 0.10.2 (Unitree's SDK and \
                 robot) sends no multicast on it and finds other participants only through configured peers \
                 (<Peers><Peer address=\"127.0.0.1\"/></Peers> with <ParticipantIndex>auto</ParticipantIndex>); \
                 Cyclone 11 (newer unitree_sdk2py wheels, ROS 2) still uses multicast on {}. Two programs that both \
                 keep Unitree's default configuration (ChannelFactoryInitialize(domain, \"{}\")) only see each other \
                 if both are Cyclone 11; configure peers in one of them (ulab's tools always do)",
                iface.name, iface.name, iface.name
            ),
        });
    }

    let mut scan: BTreeSet<u32> = match &args.scan_domains {
        Some(d) => d.0.iter().copied().collect(),
        None => [1].into_iter().chain(args.allow_robot.then_some(0)).collect(),
    };
    if !args.allow_robot && scan.remove(&0) {
        findings.push(Finding {
            code: "domain-0-not-scanned",
            severity: Severity::Info,
            message: "domain 0 (real robots) was not scanned: pass --allow-robot to look there".into(),
        });
    }
    scan.insert(args.domain);
    let loopback = iface.loopback;
    let peers: Vec<Ipv4Addr> = if loopback { vec![Ipv4Addr::LOCALHOST] } else { Vec::new() };
    let wait = Duration::from_secs_f64(args.seconds);

    // Endpoint discovery on the client's domain runs while the probe does.
    let participant = Participant::new(cfg.clone()).context("opening the DDS domain")?;
    let monitor = participant.discovery().context("watching discovery")?;
    let own = prefix_of(&monitor.own_participant_guid());
    let target = ProbeTarget {
        domains: scan.iter().copied().collect(),
        interface: args.interface.clone(),
        peers,
        max_participant_index: args.max_participant_index,
        multicast: true,
        duration: wait,
        allow_robot: args.allow_robot,
    };
    let announced = probe::probe(&target, &[own]).context("probing for participants")?;

    // The other domains with participants: their endpoints too (a participant there is what the client missed).
    let mut monitors = vec![(args.domain, monitor, participant)];
    for d in announced.iter().map(|p| p.domain).filter(|d| *d != args.domain).collect::<BTreeSet<_>>() {
        let c = DomainConfig::loopback(d).interface(args.interface.clone()).allow_robot(args.allow_robot);
        match Participant::new(c).and_then(|p| p.discovery().map(|m| (m, p))) {
            Ok((m, p)) => monitors.push((d, m, p)),
            Err(e) => eprintln!("doctor: cannot look at domain {d}'s endpoints: {e}"),
        }
    }
    let endpoints = settle_endpoints(&monitors, &announced, wait)?;

    let mut participants = Vec::new();
    let mut other_domains: BTreeMap<u32, Vec<ParticipantReport>> = BTreeMap::new();
    for a in announced {
        let eps: Vec<EndpointReport> = endpoints
            .get(&(a.domain, a.guid_prefix.clone()))
            .map(|v| v.iter().map(endpoint_report).collect())
            .unwrap_or_default();
        let r = ParticipantReport { announced: a, endpoints: eps };
        if r.announced.domain == args.domain {
            participants.push(r);
        } else {
            other_domains.entry(r.announced.domain).or_default().push(r);
        }
    }
    findings.extend(analyse(args.domain, &iface, &participants, &other_domains));
    findings.sort_by_key(|f| f.severity);
    Ok(Report {
        domain: args.domain,
        interface: args.interface.clone(),
        interfaces,
        participants,
        other_domains,
        scanned_domains: scan.into_iter().collect(),
        findings,
    })
}

fn prefix_of(guid: &[u8; 16]) -> [u8; 12] {
    let mut p = [0u8; 12];
    p.copy_from_slice(&guid[..12]);
    p
}

/// Endpoints per (domain, participant prefix), read until every announced participant with endpoints has shown
/// them and nothing changed for half a second (at most `wait` more).
fn settle_endpoints(
    monitors: &[(u32, dds_transport::DiscoveryMonitor, Participant)],
    announced: &[AnnouncedParticipant],
    wait: Duration,
) -> Result<BTreeMap<(u32, String), Vec<DiscoveredEndpoint>>> {
    let deadline = Instant::now() + wait;
    let mut last: Option<(BTreeMap<(u32, String), Vec<DiscoveredEndpoint>>, Instant)> = None;
    loop {
        let mut now_map: BTreeMap<(u32, String), Vec<DiscoveredEndpoint>> = BTreeMap::new();
        for (domain, m, _) in monitors {
            for e in m.endpoints().context("reading discovery")? {
                if e.local || !e.alive {
                    continue;
                }
                now_map.entry((*domain, probe::guid_prefix_hex(&e.participant_guid))).or_default().push(e);
            }
        }
        let all_seen = announced.iter().all(|a| now_map.contains_key(&(a.domain, a.guid_prefix.clone())));
        let stable = match &last {
            Some((prev, since)) if prev == &now_map => since.elapsed() >= Duration::from_millis(500),
            _ => {
                last = Some((now_map.clone(), Instant::now()));
                false
            }
        };
        if (all_seen && stable) || Instant::now() >= deadline {
            return Ok(now_map);
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn endpoint_report(e: &DiscoveredEndpoint) -> EndpointReport {
    EndpointReport {
        kind: match e.kind {
            EndpointKind::Publication => "writer",
            EndpointKind::Subscription => "reader",
        },
        topic: e.topic_name.clone(),
        type_name: e.type_name.clone(),
        reliability: e.reliability.map(|r| match r {
            Reliability::Reliable => "reliable",
            Reliability::BestEffort => "best-effort",
        }),
        durability: e.durability.map(durability_name),
        history: e.history_depth,
        type_information: e.has_type_information,
    }
}

fn durability_name(d: Durability) -> &'static str {
    match d {
        Durability::Volatile => "volatile",
        Durability::TransientLocal => "transient-local",
        Durability::Transient => "transient",
        Durability::Persistent => "persistent",
    }
}

fn durability_rank(name: &str) -> u8 {
    match name {
        "volatile" => 0,
        "transient-local" => 1,
        "transient" => 2,
        _ => 3,
    }
}

/// Who a participant is, in a few words: `python (pid 1457, Eclipse Cyclone DDS 11.0.1)`.
fn who(p: &ParticipantReport) -> String {
    let a = &p.announced;
    let name = a.process.clone().unwrap_or_else(|| format!("participant {}", &a.guid_prefix));
    let vendor = a.vendor.unwrap_or("unknown vendor");
    let version = a.product_version.as_deref().map(|v| format!(" {v}")).unwrap_or_default();
    match &a.pid {
        Some(pid) => format!("{name} (pid {pid}, {vendor}{version})"),
        None => format!("{name} ({vendor}{version})"),
    }
}

/// Major.minor of a Cyclone product version (`0.10.2` -> (0, 10)).
fn cyclone_series(p: &ParticipantReport) -> Option<(u32, u32)> {
    if p.announced.vendor_id != "01.10" {
        return None;
    }
    let v = p.announced.product_version.as_deref()?;
    let mut it = v.split('.').map(|x| x.parse::<u32>().ok());
    Some((it.next()??, it.next()??))
}

/// The checks. Each one states the fix; see the module docs for the exit code.
pub fn analyse(
    domain: u32,
    iface: &NetInterface,
    participants: &[ParticipantReport],
    others: &BTreeMap<u32, Vec<ParticipantReport>>,
) -> Vec<Finding> {
    let mut out = Vec::new();
    let writes =
        |p: &ParticipantReport, topic: &str| p.endpoints.iter().any(|e| e.kind == "writer" && e.topic == topic);

    if participants.is_empty() {
        out.push(Finding {
            code: "no-participants",
            severity: Severity::Problem,
            message: format!(
                "no DDS participant answered on domain {domain} through {}: nothing is running there, or it uses \
                 another domain or interface (see below), or it cannot be reached from here",
                iface.name
            ),
        });
    }

    // rt/lowstate: the robot (or a simulator) publishes it; a client that sees nothing usually lacks it.
    let lowstate = unitree_idl::topics::LOWSTATE;
    if !participants.iter().any(|p| writes(p, lowstate)) {
        let elsewhere: Vec<(u32, String)> = others
            .iter()
            .flat_map(|(d, ps)| ps.iter().filter(|p| writes(p, lowstate)).map(move |p| (*d, who(p))))
            .collect();
        if let Some((other, name)) = elsewhere.first() {
            out.push(Finding {
                code: "wrong-domain",
                severity: Severity::Problem,
                message: format!(
                    "nothing publishes {lowstate} on domain {domain}; a participant on domain {other} does ({name}): \
                     use domain {other} in the client (ChannelFactoryInitialize({other}, \"{}\"), --domain {other}), \
                     or start the robot side on domain {domain}",
                    iface.name
                ),
            });
        } else {
            out.push(Finding {
                code: "no-lowstate",
                severity: Severity::Problem,
                message: format!(
                    "nothing publishes {lowstate} on domain {domain} (nor on the other domains scanned): no robot or \
                     simulator is running there; start one (`ulab sim --domain {domain}`), or check the robot side's \
                     domain and interface"
                ),
            });
        }
    }

    // Cyclone 0.10.x crashes on the XTypes type information of Cyclone 11 endpoints.
    let old: Vec<&ParticipantReport> = participants
        .iter()
        .filter(|p| cyclone_series(p).is_some_and(|(major, minor)| major == 0 && minor <= 10))
        .collect();
    if let Some(victim) = old.first() {
        for p in participants {
            let newer = cyclone_series(p).is_some_and(|(major, minor)| major > 0 || minor > 10);
            let typed: BTreeSet<&str> =
                p.endpoints.iter().filter(|e| e.type_information).map(|e| e.topic.as_str()).collect();
            if newer && !typed.is_empty() {
                out.push(Finding {
                    code: "xtypes-with-0.10",
                    severity: Severity::Problem,
                    message: format!(
                        "the robot side runs Cyclone DDS {} ({}) and {} announces XTypes type information on {}, \
                         which crashes Cyclone 0.10.2 readers (`invalid type object`): run that client on Cyclone \
                         0.10.2 (unitree_sdk2py pins cyclonedds==0.10.2; Unitree's C++ SDK ships it), or publish \
                         without type information (ulab's transport: `ulab replay`, `ulab sim`)",
                        victim.announced.product_version.as_deref().unwrap_or("0.10"),
                        who(victim),
                        who(p),
                        typed.into_iter().collect::<Vec<_>>().join(", ")
                    ),
                });
            }
        }
    }

    // Writers and readers of one topic that can never match.
    let mut topics: BTreeMap<&str, Vec<(&ParticipantReport, &EndpointReport)>> = BTreeMap::new();
    for p in participants {
        for e in &p.endpoints {
            topics.entry(e.topic.as_str()).or_default().push((p, e));
        }
    }
    for (topic, eps) in &topics {
        let writers: Vec<_> = eps.iter().filter(|(_, e)| e.kind == "writer").collect();
        let readers: Vec<_> = eps.iter().filter(|(_, e)| e.kind == "reader").collect();
        for (rp, r) in &readers {
            for (wp, w) in &writers {
                if r.type_name != w.type_name {
                    out.push(Finding {
                        code: "type-mismatch",
                        severity: Severity::Problem,
                        message: format!(
                            "{topic}: {} publishes {} but {} subscribes {}: different type names never match; \
                             use the writer's type (H1-2 and G1 speak unitree_hg, Go2, B2 and H1 unitree_go)",
                            who(wp),
                            w.type_name,
                            who(rp),
                            r.type_name
                        ),
                    });
                    continue;
                }
                if r.reliability == Some("reliable") && w.reliability == Some("best-effort") {
                    out.push(Finding {
                        code: "qos-incompatible",
                        severity: Severity::Problem,
                        message: format!(
                            "{topic}: {} asks for RELIABLE delivery but {} offers only BEST_EFFORT: they never match; \
                             make the reader best-effort (Unitree's default for readers) or the writer reliable",
                            who(rp),
                            who(wp)
                        ),
                    });
                }
                if let (Some(rd), Some(wd)) = (r.durability, w.durability) {
                    if durability_rank(rd) > durability_rank(wd) {
                        out.push(Finding {
                            code: "qos-incompatible",
                            severity: Severity::Problem,
                            message: format!(
                                "{topic}: {} asks for {rd} durability but {} offers {wd}: they never match; ask \
                                 for volatile (Unitree's default) or make the writer {rd}",
                                who(rp),
                                who(wp)
                            ),
                        });
                    }
                }
            }
        }
    }
    out
}

fn text(r: &Report) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ =
        writeln!(s, "ulab doctor: domain {} on {} (scanned domains {:?})\n", r.domain, r.interface, r.scanned_domains);
    let _ = writeln!(s, "interfaces");
    for i in &r.interfaces {
        let addrs: Vec<String> = i.ipv4.iter().map(Ipv4Addr::to_string).collect();
        let _ = writeln!(
            s,
            "  {:<10} {:<5} {:<9} {:<19} {}",
            i.name,
            if i.up { "up" } else { "down" },
            if i.loopback { "loopback" } else { "" },
            if i.multicast_flag { "multicast" } else { "no MULTICAST flag" },
            addrs.join(" ")
        );
    }
    let mut participants = |title: String, ps: &[ParticipantReport]| {
        let _ = writeln!(s, "\n{title} ({})", ps.len());
        for p in ps {
            let a = &p.announced;
            let _ = writeln!(
                s,
                "  {}  {} {} (vendor {}, RTPS {})  process {} pid {} host {}  at {}",
                a.guid_prefix,
                a.vendor.unwrap_or("unknown vendor"),
                a.product_version.as_deref().unwrap_or("?"),
                a.vendor_id,
                a.protocol_version,
                a.process.as_deref().unwrap_or("?"),
                a.pid.as_deref().unwrap_or("?"),
                a.hostname.as_deref().unwrap_or("?"),
                a.source
            );
            for e in &p.endpoints {
                let _ = writeln!(
                    s,
                    "    {:<6} {:<24} {:<40} {} {} {}{}",
                    e.kind,
                    e.topic,
                    e.type_name,
                    e.reliability.unwrap_or("?"),
                    e.durability.unwrap_or("?"),
                    match e.history {
                        Some(-1) => "keep-all".to_owned(),
                        Some(d) => format!("keep-last {d}"),
                        None => "?".to_owned(),
                    },
                    if e.type_information { "  XTypes type information" } else { "" }
                );
            }
        }
    };
    participants(format!("participants on domain {}", r.domain), &r.participants);
    for (d, ps) in &r.other_domains {
        participants(format!("participants on domain {d}"), ps);
    }
    let _ = writeln!(s, "\nfindings");
    if r.findings.is_empty() {
        let _ = writeln!(s, "  none: the domain looks healthy from here");
    }
    for f in &r.findings {
        let sev = match f.severity {
            Severity::Problem => "PROBLEM",
            Severity::Warning => "warning",
            Severity::Info => "info",
        };
        let _ = writeln!(s, "  {sev} [{}] {}", f.code, f.message);
    }
    s
}
