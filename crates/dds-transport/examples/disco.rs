//! Prints the endpoints seen in discovery. usage: disco DOMAIN [SECONDS]
use dds_transport::{DomainConfig, Participant};
use std::time::Duration;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let domain: u32 = std::env::args().nth(1).map_or(Ok(1), |s| s.parse())?;
    let secs: u64 = std::env::args().nth(2).map_or(Ok(3), |s| s.parse())?;
    let p = Participant::new(DomainConfig::loopback(domain))?;
    // With ULAB_DISCO_ENDPOINTS set, our own LowCmd writer / LowState reader exist first.
    let _own = if std::env::var_os("ULAB_DISCO_ENDPOINTS").is_some() {
        let fam = dds_transport::Family::Hg;
        Some((p.writer(&dds_transport::TopicSpec::lowcmd(fam))?, p.reader(&dds_transport::TopicSpec::lowstate(fam))?))
    } else {
        None
    };
    let mon = p.discovery()?;
    std::thread::sleep(Duration::from_secs(secs));
    for e in mon.endpoints()? {
        println!(
            "{:?} {} {} local={} type_info={} {:?} depth={:?} {:?}",
            e.kind,
            e.topic_name,
            e.type_name,
            e.local,
            e.has_type_information,
            e.reliability,
            e.history_depth,
            e.durability
        );
    }
    Ok(())
}
