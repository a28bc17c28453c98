//! Transport round-trip time between two processes on loopback (the floor under any
//! command-to-state latency). Run `rtt echo D` in one shell and `rtt ping D [N]` in another:
//! ping writes hg-LowCmd-sized samples on rt/lowcmd at 500 Hz, echo answers each on rt/lowstate
//! with a LowState-sized sample, ping prints p50/p99/max of the round trip.
use dds_transport::{topics::Family, DomainConfig, Participant, TopicSpec};
use std::time::{Duration, Instant};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let mode = args.get(1).cloned().unwrap_or_default();
    let domain: u32 = args.get(2).map_or(Ok(1), |s| s.parse())?;
    let n: usize = args.get(3).map_or(Ok(2000), |s| s.parse())?;
    let p = Participant::new(DomainConfig::loopback(domain))?;
    let cmd = TopicSpec::lowcmd(Family::Hg);
    let state = TopicSpec::lowstate(Family::Hg);
    match mode.as_str() {
        "echo" => {
            let w = p.writer(&state)?;
            let r = p.reader(&cmd)?;
            let mut out = vec![0u8; 2092];
            out[1] = 1;
            let end = Instant::now() + Duration::from_secs(60);
            while Instant::now() < end {
                if let Some(s) = r.take(Duration::from_millis(100)) {
                    out[4..12].copy_from_slice(&s.data[4..12]);
                    w.write(&out)?;
                }
            }
        }
        "ping" => {
            let w = p.writer(&cmd)?;
            let r = p.reader(&state)?;
            if !w.wait_for_readers(1, Duration::from_secs(10))? || !r.wait_for_writers(1, Duration::from_secs(10))? {
                return Err("echo not found".into());
            }
            let mut msg = vec![0u8; 1004];
            msg[1] = 1;
            let t0 = Instant::now();
            let mut rtts = Vec::with_capacity(n);
            let mut lost = 0;
            for i in 0..n as u64 {
                let due = t0 + Duration::from_micros(2000 * i);
                if let Some(d) = due.checked_duration_since(Instant::now()) {
                    std::thread::sleep(d);
                }
                msg[4..12].copy_from_slice(&i.to_le_bytes());
                let sent = Instant::now();
                w.write(&msg)?;
                loop {
                    match r.take(Duration::from_millis(50)) {
                        Some(s) if s.data.get(4..12) == Some(&i.to_le_bytes()[..]) => {
                            rtts.push(sent.elapsed());
                            break;
                        }
                        Some(_) => continue,
                        None => {
                            lost += 1;
                            break;
                        }
                    }
                }
            }
            rtts.sort();
            let q = |f: f64| rtts.get(((rtts.len() as f64 - 1.0) * f) as usize).map_or(0.0, |d| d.as_secs_f64() * 1e6);
            println!(
                "round trips {} lost {lost}: p50 {:.0} us, p99 {:.0} us, max {:.0} us",
                rtts.len(),
                q(0.5),
                q(0.99),
                q(1.0)
            );
        }
        _ => return Err("usage: rtt echo|ping DOMAIN [N]".into()),
    }
    Ok(())
}
