//! Listens on rt/lowstate (hg) or another topic and prints what arrives.
//! usage: listen DOMAIN [SECONDS] [TOPIC TYPE] ; ULAB_DDS_TRACE=/tmp/file enables Cyclone tracing.
use dds_transport::{DomainConfig, Participant, TopicSpec};
use std::time::{Duration, Instant};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let domain: u32 = args.get(1).map_or(Ok(1), |s| s.parse())?;
    let secs: u64 = args.get(2).map_or(Ok(5), |s| s.parse())?;
    let topic = match (args.get(3), args.get(4)) {
        (Some(t), Some(ty)) => TopicSpec::new(t.clone(), ty.clone()),
        _ => TopicSpec::lowstate(dds_transport::Family::Hg),
    };
    let mut cfg = DomainConfig::loopback(domain);
    if let Ok(f) = std::env::var("ULAB_DDS_TRACE") {
        cfg = cfg.tracing("finest", f);
    }
    let p = Participant::new(cfg)?;
    let r = p.reader(&topic)?;
    let end = Instant::now() + Duration::from_secs(secs);
    let mut n = 0u64;
    while Instant::now() < end {
        if let Some(s) = r.take(Duration::from_millis(100)) {
            n += 1;
            if n <= 3 || n.is_multiple_of(100) {
                println!("sample {n}: {} bytes, matched writers {}", s.data.len(), r.matched_writers()?);
            }
        }
    }
    println!("total {n}, matched writers {}", r.matched_writers()?);
    Ok(())
}
