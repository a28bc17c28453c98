//! Sends malformed hg LowCmd_ samples on rt/lowcmd (for robustness experiments against a peer).
//! usage: malformed DOMAIN
use dds_transport::{topics::Family, DomainConfig, Participant, TopicSpec};
use std::time::Duration;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let domain: u32 = std::env::args().nth(1).map_or(Ok(1), |s| s.parse())?;
    let p = Participant::new(DomainConfig::loopback(domain))?;
    let w = p.writer(&TopicSpec::lowcmd(Family::Hg))?;
    if !w.wait_for_readers(1, Duration::from_secs(5))? {
        return Err("no reader".into());
    }
    let mut good = vec![0u8; 1004];
    good[1] = 1;
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("header only", vec![0, 1, 0, 0]),
        ("truncated 100", good[..100].to_vec()),
        ("truncated 1003", good[..1003].to_vec()),
        ("oversize 4000", {
            let mut v = good.clone();
            v.resize(4000, 0xAB);
            v
        }),
        ("xcdr2 header", {
            let mut v = good.clone();
            v[1] = 7;
            v
        }),
        ("big endian", {
            let mut v = good.clone();
            v[1] = 0;
            v
        }),
        ("unknown encapsulation", {
            let mut v = good.clone();
            v[0] = 0x55;
            v[1] = 0x55;
            v
        }),
        ("pl_cdr", {
            let mut v = good.clone();
            v[1] = 3;
            v
        }),
        ("garbage", (0..1004u32).map(|i| (i * 37 % 256) as u8).collect()),
        ("good", good.clone()),
    ];
    for (name, bytes) in &cases {
        for _ in 0..5 {
            w.write(bytes)?;
            std::thread::sleep(Duration::from_millis(20));
        }
        println!("sent {name} ({} bytes)", bytes.len());
    }
    std::thread::sleep(Duration::from_millis(300));
    Ok(())
}
