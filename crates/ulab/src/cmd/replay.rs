//! `ulab replay`: republishes the messages of an MCAP recording over DDS with their original
//! timing (log time, i.e. reception time at recording), optionally sped up or slowed down.

use super::recording::NetArgs;
use crate::exit::Exit;
use anyhow::{bail, Context, Result};
use dds_transport::{Participant, RawWriter, TopicSpec};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Arguments of `ulab replay`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// MCAP file written by `ulab record` (or any MCAP with `cdr` messages and DDS type names).
    pub file: PathBuf,
    #[command(flatten)]
    pub net: NetArgs,
    /// Time scale: 2 plays twice as fast, 0.5 at half speed.
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Only these topics (default: all).
    #[arg(long, num_args = 1.., value_delimiter = ',')]
    pub topics: Vec<String>,
    /// Before starting, wait up to this many seconds for every topic to have `--min-readers` subscribers.
    #[arg(long, default_value_t = 5.0)]
    pub wait_readers: f64,
    /// Subscribers each topic must have before the replay starts (e.g. 2: the robot and a recorder), waited for
    /// up to `--wait-readers` seconds.
    #[arg(long, default_value_t = 1)]
    pub min_readers: u32,
}

struct Msg<'a> {
    log_time: u64,
    writer: usize,
    data: std::borrow::Cow<'a, [u8]>,
}

pub fn run(args: Args) -> Result<Exit> {
    if !(args.speed.is_finite() && args.speed > 0.0) {
        bail!("--speed must be a positive number");
    }
    if !(args.wait_readers.is_finite() && args.wait_readers >= 0.0) {
        bail!("--wait-readers must be a non-negative number of seconds");
    }
    let cfg = args.net.domain_config()?;
    let bytes = std::fs::read(&args.file).with_context(|| format!("reading {}", args.file.display()))?;

    // Topic and DDS type of each channel; one writer per topic.
    let mut specs: Vec<TopicSpec> = Vec::new();
    let mut by_channel: BTreeMap<u16, usize> = BTreeMap::new();
    let mut msgs: Vec<Msg<'_>> = Vec::new();
    let mut skipped = 0u64;
    for m in recording::messages(&bytes).with_context(|| format!("reading {}", args.file.display()))? {
        let m = m.with_context(|| format!("reading {}", args.file.display()))?;
        let ch = &m.channel;
        if !args.topics.is_empty() && !args.topics.iter().any(|t| t == &ch.topic) {
            continue;
        }
        if ch.message_encoding != recording::MESSAGE_ENCODING {
            skipped += 1;
            continue;
        }
        let w = match by_channel.get(&ch.id) {
            Some(w) => *w,
            None => {
                let type_name = recording::channel_type_name(ch)
                    .filter(|n| !n.is_empty())
                    .with_context(|| format!("channel {} has no DDS type name", ch.topic))?;
                let spec = TopicSpec::new(ch.topic.clone(), type_name);
                let w = match specs.iter().position(|s| *s == spec) {
                    Some(w) => w,
                    None => {
                        if specs.iter().any(|s| s.name == spec.name) {
                            bail!("topic {} appears with two DDS types", spec.name);
                        }
                        specs.push(spec);
                        specs.len() - 1
                    }
                };
                by_channel.insert(ch.id, w);
                w
            }
        };
        msgs.push(Msg { log_time: m.log_time, writer: w, data: m.data });
    }
    if msgs.is_empty() {
        bail!("{} holds no messages to replay", args.file.display());
    }
    msgs.sort_by_key(|m| m.log_time); // stable: keeps file order for equal times

    let participant = Participant::new(cfg.clone()).context("opening the DDS domain")?;
    let writers: Vec<RawWriter> = specs
        .iter()
        .map(|s| participant.writer(s).with_context(|| format!("publishing {}", s.name)))
        .collect::<Result<_>>()?;
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        if let Err(e) = ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst)) {
            eprintln!("warning: cannot install the Ctrl-C handler ({e})");
        }
    }
    let wait_until = Instant::now() + Duration::from_secs_f64(args.wait_readers);
    for w in &writers {
        let left = wait_until.saturating_duration_since(Instant::now());
        if !w.wait_for_readers(args.min_readers, left)? {
            eprintln!(
                "warning: fewer than {} subscriber(s) on {} yet; publishing anyway",
                args.min_readers,
                w.topic().name
            );
        }
    }
    let first = msgs[0].log_time;
    let span = msgs[msgs.len() - 1].log_time.saturating_sub(first) as f64 / 1e9;
    eprintln!(
        "replaying {} messages ({span:.2} s of recording) on domain {} / {} at speed {}",
        msgs.len(),
        cfg.domain_id(),
        cfg.interface_name(),
        args.speed
    );

    let start = Instant::now();
    let mut sent = vec![0u64; writers.len()];
    let mut errors = 0u64;
    let mut max_late = Duration::ZERO;
    for m in &msgs {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        let offset = Duration::from_secs_f64((m.log_time - first) as f64 / 1e9 / args.speed);
        let due = start + offset;
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        } else {
            max_late = max_late.max(now - due);
        }
        match writers[m.writer].write(&m.data) {
            Ok(()) => sent[m.writer] += 1,
            Err(e) => {
                errors += 1;
                if errors <= 5 {
                    eprintln!("warning: {}: {e}", specs[m.writer].name);
                }
            }
        }
    }
    // Give reliable delivery a moment before the writers go away.
    std::thread::sleep(Duration::from_millis(200));
    for (s, n) in specs.iter().zip(&sent) {
        println!("{}: {n} messages sent", s.name);
    }
    println!(
        "took {:.2} s, latest message {:.2} ms behind schedule",
        start.elapsed().as_secs_f64(),
        max_late.as_secs_f64() * 1e3
    );
    if skipped > 0 {
        println!("{skipped} messages skipped (not cdr)");
    }
    if errors > 0 {
        bail!("{errors} messages could not be published");
    }
    Ok(Exit::Success)
}
