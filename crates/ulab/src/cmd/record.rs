//! `ulab record`: subscribes Unitree topics over DDS and writes them to an MCAP file.
//!
//! The file follows the `recording` crate's format (each message as received, CDR with its
//! encapsulation header; OMG IDL schemas; log time is the reception time), publish time is the
//! writer's source timestamp. Ctrl-C (or --duration) ends the
//! recording and the file is finished properly. At the end, gaps that can be detected are
//! reported: LowState tick jumps, arrival gaps and one-second windows with a low rate.
//!
//! `--split-minutes` starts a new file every so often, each finished and indexed. Why: an indexed MCAP
//! writer keeps one index entry per chunk until the file is finished (a few hundred bytes per 256-KiB
//! chunk, ~150 KiB a minute at 500 Hz), so one endless file makes the recorder's memory grow with it.

mod gaps;

use super::recording::{parse_topic, NetArgs, TopicChoice};
use crate::exit::Exit;
use anyhow::{bail, Context, Result};
use dds_transport::{Participant, ReaderOptions, Sample};
use recording::lowstate_tick;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};

/// `--compression`: MCAP chunk compression (`recording::Compression`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CompressionArg {
    /// Cheapest while recording.
    None,
    /// About 5x smaller; what the official writers use by default.
    Zstd,
    Lz4,
}

/// `--family`: the message family of rt/lowcmd and rt/lowstate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FamilyArg {
    /// `unitree_hg` (H1-2, G1).
    Hg,
    /// `unitree_go` (Go2, H1, B2).
    Go,
}

impl FamilyArg {
    /// The codec's family prefix (`hg/LowCmd`).
    pub fn name(self) -> &'static str {
        match self {
            FamilyArg::Hg => "hg",
            FamilyArg::Go => "go",
        }
    }
}

/// Arguments of `ulab record`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub net: NetArgs,
    /// Output MCAP file.
    #[arg(long)]
    pub out: PathBuf,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Topics to record: rt/lowcmd, rt/lowstate, rt/sportmodestate, or TOPIC=TYPE with TYPE a codec name
    /// (hg/HandState) or a DDS type name. Default: rt/lowcmd, rt/lowstate and rt/sportmodestate (the base pose
    /// a simulator publishes; `ulab render` uses it).
    #[arg(long, num_args = 1.., value_delimiter = ',')]
    pub topics: Vec<String>,
    /// Message family of rt/lowcmd and rt/lowstate: hg (H1-2, G1) or go (Go2, H1, B2).
    #[arg(long, value_enum, default_value_t = FamilyArg::Hg)]
    pub family: FamilyArg,
    /// Overwrite the output file if it exists.
    #[arg(long)]
    pub force: bool,
    /// Print nothing while recording, only the final report.
    #[arg(long)]
    pub quiet: bool,
    /// Chunk compression: none (cheapest while recording), zstd (about 5x smaller) or lz4.
    #[arg(long, value_enum, default_value_t = CompressionArg::None)]
    pub compression: CompressionArg,
    /// Chunk size (bytes before compression). A recorder killed without warning loses at most the chunk it was
    /// filling (`ulab log recover` copies the rest): 256 KiB is about a quarter of a second of rt/lowstate and
    /// rt/lowcmd at 500 Hz.
    #[arg(long, default_value_t = recording::CHUNK_SIZE, value_parser = clap::value_parser!(u64).range(4096..=(64 << 20)))]
    pub chunk_size: u64,
    /// Start a new file every this many minutes (fractions allowed): OUT becomes OUT_000.mcap, OUT_001.mcap, …,
    /// each finished and indexed, so memory stays bounded however long the recording runs (one file keeps its
    /// chunk index in memory until it is finished). Nothing is lost or duplicated at the seams.
    #[arg(long)]
    pub split_minutes: Option<f64>,
    /// Socket receive buffer to ask the kernel for (bytes). While the recorder is descheduled, samples wait
    /// there; Cyclone's default 1 MiB holds about one second of hg LowState at 500 Hz. The kernel grants at most
    /// net.core.rmem_max: a warning says so when that is less than a size given here, or, for the default of
    /// 8 MiB, less than Cyclone's own 1 MiB (a stock kernel's 208 KiB).
    #[arg(long, value_parser = clap::value_parser!(u64).range(65536..=(1 << 30)))]
    pub socket_buffer: Option<u64>,
}

/// `--socket-buffer` default: 8 MiB, several seconds of rt/lowstate and rt/lowcmd at 500 Hz.
pub const DEFAULT_SOCKET_BUFFER: u64 = 8 << 20;

/// Cyclone DDS's own socket receive buffer when nobody asks for one.
const CYCLONE_SOCKET_BUFFER: u64 = 1 << 20;

/// The kernel's cap on a socket receive buffer (`net.core.rmem_max`), where Linux tells it.
fn kernel_rmem_max() -> Option<u64> {
    std::fs::read_to_string("/proc/sys/net/core/rmem_max").ok()?.trim().parse().ok()
}

/// The warning for a kernel cap `cap` under the buffer asked for, if one is due: always when the user named a
/// size, and for the default only when the cap leaves the recorder worse off than Cyclone's own 1 MiB (a warning
/// on every run of a machine whose administrator chose 4 MiB would teach users to ignore it).
fn socket_buffer_warning(asked: Option<u64>, cap: u64) -> Option<String> {
    let (want, floor) = match asked {
        Some(n) => (n, n),
        None => (DEFAULT_SOCKET_BUFFER, CYCLONE_SOCKET_BUFFER),
    };
    (cap < floor).then(|| {
        format!(
            "warning: the kernel grants socket buffers of at most {cap} bytes (net.core.rmem_max), less than the \
             {want} asked for: a recorder descheduled for longer than that holds loses samples \
             (`sysctl -w net.core.rmem_max={want}` raises the cap)"
        )
    })
}

/// The files of one recording: OUT itself, or numbered segments of it with `--split-minutes`.
struct Segments {
    out: PathBuf,
    split: Option<Duration>,
    next: usize,
    force: bool,
}

impl Segments {
    /// The path of segment `i` (`run.mcap` → `run_000.mcap`).
    fn path(&self, i: usize) -> PathBuf {
        if self.split.is_none() {
            return self.out.clone();
        }
        let stem = self.out.file_stem().map_or_else(|| "recording".into(), |s| s.to_string_lossy().into_owned());
        let ext = self.out.extension().map_or_else(|| "mcap".into(), |s| s.to_string_lossy().into_owned());
        self.out.with_file_name(format!("{stem}_{i:03}.{ext}"))
    }

    /// Creates the next file with every channel (their ids are set anew).
    fn open(&mut self, opts: &mcap::WriteOptions, channels: &mut [Channel]) -> Result<mcap::Writer<BufWriter<File>>> {
        let path = self.path(self.next);
        if path.exists() && !self.force {
            bail!("{} exists (use --force to overwrite)", path.display());
        }
        let file = File::create(&path).with_context(|| format!("creating {}", path.display()))?;
        let mut writer = opts.clone().create(BufWriter::new(file)).context("starting the MCAP file")?;
        for ch in channels.iter_mut() {
            ch.id = recording::add_topic(&mut writer, &ch.choice.spec.name, &ch.choice.spec.type_name)
                .with_context(|| format!("adding the channel of {}", ch.choice.spec.name))?;
        }
        self.next += 1;
        Ok(writer)
    }
}

struct Channel {
    choice: TopicChoice,
    id: u16,
    sequence: u32,
    stats: gaps::GapStats,
}

fn now_ns() -> u64 {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u64)
}

/// What `ulab record` records without `--topics`.
pub const DEFAULT_TOPICS: [&str; 3] = ["rt/lowcmd", "rt/lowstate", unitree_idl::topics::SPORTMODESTATE];

pub fn run(args: Args) -> Result<Exit> {
    let cfg = args.net.domain_config()?.socket_receive_buffer(args.socket_buffer.unwrap_or(DEFAULT_SOCKET_BUFFER));
    if let Some(w) = kernel_rmem_max().and_then(|cap| socket_buffer_warning(args.socket_buffer, cap)) {
        eprintln!("{w}");
    }
    if let Some(d) = args.duration {
        if !(d.is_finite() && d > 0.0) {
            bail!("--duration must be a positive number of seconds");
        }
    }
    let texts: Vec<String> =
        if args.topics.is_empty() { DEFAULT_TOPICS.map(str::to_owned).to_vec() } else { args.topics.clone() };
    let mut choices: Vec<TopicChoice> = Vec::new();
    for t in &texts {
        let c = parse_topic(t, args.family.name())?;
        if choices.iter().any(|o| o.spec.name == c.spec.name) {
            bail!("topic {} listed twice", c.spec.name);
        }
        choices.push(c);
    }
    let split = match args.split_minutes {
        None => None,
        Some(m) if m.is_finite() && m > 0.0 && m <= 1e6 => Some(Duration::from_secs_f64(m * 60.0)),
        Some(_) => bail!("--split-minutes must be a positive number of minutes"),
    };
    let mut segments = Segments { out: args.out.clone(), split, next: 0, force: args.force };
    let compression = match args.compression {
        CompressionArg::None => recording::Compression::None,
        CompressionArg::Zstd => recording::Compression::Zstd,
        CompressionArg::Lz4 => recording::Compression::Lz4,
    };
    let opts = recording::write_options_with_chunk_size(
        concat!("ulab ", env!("CARGO_PKG_VERSION")),
        compression,
        args.chunk_size,
    );
    let mut channels: Vec<Channel> = choices
        .into_iter()
        .map(|choice| Channel { choice, id: 0, sequence: 0, stats: gaps::GapStats::default() })
        .collect();
    let mut writer = segments.open(&opts, &mut channels)?;
    let mut segment_started = Instant::now();

    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        if let Err(e) = ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst)) {
            eprintln!("warning: cannot install the Ctrl-C handler ({e}); use --duration");
        }
    }

    let participant = Participant::new(cfg.clone()).context("opening the DDS domain")?;
    let (tx, rx) = mpsc::sync_channel::<(usize, Sample)>(1 << 16);
    let overflow = Arc::new(AtomicU64::new(0));
    let mut readers = Vec::new();
    for (i, ch) in channels.iter().enumerate() {
        let tx = tx.clone();
        let overflow = overflow.clone();
        let opts = ReaderOptions { history_depth: 64, ..ReaderOptions::default() };
        let r = participant
            .reader_with_callback(&ch.choice.spec, opts, move |s| {
                if tx.try_send((i, s)).is_err() {
                    overflow.fetch_add(1, Ordering::Relaxed);
                }
            })
            .with_context(|| format!("subscribing {}", ch.choice.spec.name))?;
        readers.push(r);
    }
    drop(tx);
    if !args.quiet {
        eprintln!(
            "recording {} on domain {} / {} into {} ({})",
            channels.iter().map(|c| c.choice.spec.name.as_str()).collect::<Vec<_>>().join(", "),
            cfg.domain_id(),
            cfg.interface_name(),
            segments.path(0).display(),
            match args.duration {
                Some(d) => format!("{d} s"),
                None => "Ctrl-C to stop".to_owned(),
            }
        );
    }

    let started = Instant::now();
    let started_ns = now_ns();
    let deadline = args.duration.map(|d| started + Duration::from_secs_f64(d));
    let mut last_status = Instant::now();
    let mut counts_at_status = vec![0u64; channels.len()];
    let mut write_error = None;
    loop {
        if stop.load(Ordering::SeqCst) || deadline.is_some_and(|d| Instant::now() >= d) {
            break;
        }
        match rx.recv_timeout(Duration::from_millis(50)) {
            Ok((i, s)) => {
                if let Err(e) = store(&mut writer, &mut channels[i], &s) {
                    write_error = Some(e);
                    break;
                }
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
        }
        // Samples wait in the queue meanwhile: the seam loses nothing.
        if segments.split.is_some_and(|d| segment_started.elapsed() >= d) {
            let done = segments.path(segments.next - 1);
            let mut meta = BTreeMap::new();
            meta.insert("segment".to_owned(), (segments.next - 1).to_string());
            let _ = writer.write_metadata(&mcap::records::Metadata { name: "ulab.record".to_owned(), metadata: meta });
            if let Err(e) = writer.finish() {
                write_error = Some(anyhow::Error::from(e).context(format!("finishing {}", done.display())));
                break;
            }
            match segments.open(&opts, &mut channels) {
                Ok(w) => writer = w,
                Err(e) => {
                    write_error = Some(e);
                    break;
                }
            }
            segment_started = Instant::now();
            if !args.quiet {
                eprintln!("  finished {}, now {}", done.display(), segments.path(segments.next - 1).display());
            }
        }
        if !args.quiet && last_status.elapsed() >= Duration::from_secs(5) {
            let dt = last_status.elapsed().as_secs_f64();
            let rates: Vec<String> = channels
                .iter()
                .zip(counts_at_status.iter_mut())
                .map(|(c, prev)| {
                    let n = c.stats.count();
                    let r = (n - *prev) as f64 / dt;
                    *prev = n;
                    format!("{} {r:.1} Hz", c.choice.spec.name)
                })
                .collect();
            eprintln!("  {:>6.1} s  {}", started.elapsed().as_secs_f64(), rates.join(", "));
            last_status = Instant::now();
        }
    }
    // Stop the readers first, then store what is still queued.
    drop(readers);
    drop(participant);
    if write_error.is_none() {
        while let Ok((i, s)) = rx.try_recv() {
            if let Err(e) = store(&mut writer, &mut channels[i], &s) {
                write_error = Some(e);
                break;
            }
        }
    }

    let report = Report::build(channels, overflow.load(Ordering::Relaxed), started.elapsed().as_secs_f64());
    let mut meta = BTreeMap::new();
    meta.insert("domain".to_owned(), cfg.domain_id().to_string());
    meta.insert("interface".to_owned(), cfg.interface_name().to_owned());
    meta.insert("start_ns".to_owned(), started_ns.to_string());
    meta.insert("report".to_owned(), report.text.clone());
    if segments.split.is_some() {
        meta.insert("segment".to_owned(), (segments.next - 1).to_string());
    }
    let _ = writer.write_metadata(&mcap::records::Metadata { name: "ulab.record".to_owned(), metadata: meta });
    writer.finish().context("finishing the MCAP file")?;
    drop(writer);
    print!("{}", report.text);
    if let Some(e) = write_error {
        return Err(e).context("writing the MCAP file (what was written before is kept)");
    }
    Ok(Exit::Success)
}

fn store(writer: &mut mcap::Writer<BufWriter<File>>, ch: &mut Channel, s: &Sample) -> Result<()> {
    let log_time = u64::try_from(s.reception_ns).unwrap_or(0);
    let publish_time = s.source_timestamp_ns.and_then(|t| u64::try_from(t).ok()).unwrap_or(log_time);
    writer.write_to_known_channel(
        &mcap::records::MessageHeader { channel_id: ch.id, sequence: ch.sequence, log_time, publish_time },
        &s.data,
    )?;
    ch.sequence = ch.sequence.wrapping_add(1);
    let tick = match ch.choice.kind {
        Some(kind @ (unitree_idl::MessageType::HgLowState | unitree_idl::MessageType::GoLowState)) => {
            Some(lowstate_tick(kind, &s.data))
        }
        _ => None,
    };
    ch.stats.push(s.reception_ns, tick);
    Ok(())
}

/// The end-of-recording report.
struct Report {
    text: String,
}

const MAX_LISTED: usize = 10;

impl Report {
    fn build(channels: Vec<Channel>, overflow: u64, seconds: f64) -> Self {
        let mut t = String::new();
        t.push_str(&format!("recorded {seconds:.2} s\n"));
        if overflow > 0 {
            t.push_str(&format!("warning: {overflow} samples lost: the writer could not keep up\n"));
        }
        for ch in channels {
            ch.stats.report(&ch.choice.spec.name, MAX_LISTED, &mut t);
        }
        Report { text: t }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_socket_buffer_warning_speaks_when_it_matters() {
        // A size the user named and the kernel cuts: always said.
        assert!(socket_buffer_warning(Some(8 << 20), 4 << 20).is_some());
        assert!(socket_buffer_warning(Some(2 << 20), 4 << 20).is_none());
        // The default cut to 4 MiB is still four times Cyclone's own: not worth a warning on every run.
        assert!(socket_buffer_warning(None, 4 << 20).is_none());
        // A stock kernel (208 KiB) leaves the recorder worse off than Cyclone's default: said, with the default.
        let w = socket_buffer_warning(None, 212_992).expect("warning under 1 MiB");
        assert!(w.contains("212992") && w.contains(&DEFAULT_SOCKET_BUFFER.to_string()), "{w}");
    }
}
