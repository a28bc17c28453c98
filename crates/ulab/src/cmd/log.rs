//! `ulab log`: look into MCAP recordings. `export --format csv` writes one row per message with
//! one named column per field (`motor_state[3].q`), decoded by our codec.

use crate::exit::Exit;
use anyhow::{bail, Context, Result};
use recording::columns::{column_names, decode_flat};
use recording::{channel_type_name, kind_of};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Arguments of `ulab log`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub command: LogCommand,
}

/// What to do with a recording.
#[derive(Debug, clap::Subcommand)]
pub enum LogCommand {
    /// Export messages to CSV, one row per message.
    Export(ExportArgs),
    /// Channels, types and message counts.
    Info {
        /// The MCAP file.
        file: PathBuf,
    },
    /// Copy what can be read of an unfinished recording (a recorder killed or a power cut) into a finished file.
    Recover {
        /// The unfinished MCAP file.
        file: PathBuf,
        /// The finished copy (default: FILE_STEM_recovered.mcap next to the input).
        #[arg(long)]
        out: Option<PathBuf>,
    },
}

/// Arguments of `ulab log export`.
#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// The MCAP file.
    pub file: PathBuf,
    /// Output format.
    #[arg(long, default_value = "csv", value_parser = ["csv"])]
    pub format: String,
    /// Only this topic.
    #[arg(long)]
    pub topic: Option<String>,
    /// Output: a file when one topic is exported ("-" or nothing: standard output), a directory
    /// (one TOPIC.csv per topic) otherwise (default: FILE_STEM_csv next to the input).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(args: Args) -> Result<Exit> {
    match args.command {
        LogCommand::Export(a) => export(a),
        LogCommand::Info { file } => info(&file),
        LogCommand::Recover { file, out } => recover(&file, out),
    }
}

fn recover(file: &Path, out: Option<PathBuf>) -> Result<Exit> {
    let bytes = std::fs::read(file).with_context(|| format!("reading {}", file.display()))?;
    let out = out.unwrap_or_else(|| {
        let stem = file.file_stem().map_or_else(|| "log".into(), |s| s.to_string_lossy().into_owned());
        file.with_file_name(format!("{stem}_recovered.mcap"))
    });
    if out == file {
        bail!("--out must differ from the input");
    }
    let w = std::io::BufWriter::new(create(&out)?);
    let opts =
        recording::write_options(concat!("ulab ", env!("CARGO_PKG_VERSION"), " log recover"), Default::default());
    let r = recording::recover(&bytes, w, opts).with_context(|| format!("recovering {}", file.display()))?;
    match &r.stopped_by {
        None => eprintln!("{}: read to its end (a finished file); {} messages copied", file.display(), r.messages),
        Some(why) => eprintln!("{}: {why}; the {} messages before it copied", file.display(), r.messages),
    }
    println!("{}", out.display());
    Ok(Exit::Success)
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_owned()
    }
}

struct Table {
    out: Box<dyn Write>,
    columns: Vec<String>,
    rows: u64,
}

fn export(a: ExportArgs) -> Result<Exit> {
    let bytes = std::fs::read(&a.file).with_context(|| format!("reading {}", a.file.display()))?;
    // First pass: which topics are there.
    let mut topics: BTreeMap<String, String> = BTreeMap::new();
    for m in recording::messages(&bytes).with_context(|| format!("reading {}", a.file.display()))? {
        let m = m.with_context(|| format!("reading {}", a.file.display()))?;
        let ty = channel_type_name(&m.channel);
        topics.entry(m.channel.topic.clone()).or_insert_with(|| ty.unwrap_or_default());
    }
    if let Some(t) = &a.topic {
        topics.retain(|k, _| k == t);
        if topics.is_empty() {
            bail!("topic {t} is not in {}", a.file.display());
        }
    }
    if topics.is_empty() {
        bail!("{} holds no messages", a.file.display());
    }
    let single = topics.len() == 1;
    let dir = if single {
        None
    } else {
        let d = a.out.clone().unwrap_or_else(|| {
            let stem = a.file.file_stem().map_or_else(|| "log".into(), |s| s.to_string_lossy().into_owned());
            a.file.with_file_name(format!("{stem}_csv"))
        });
        std::fs::create_dir_all(&d).with_context(|| format!("creating {}", d.display()))?;
        Some(d)
    };
    let mut tables: BTreeMap<String, Table> = BTreeMap::new();
    for (topic, ty) in &topics {
        let (out, path): (Box<dyn Write>, Option<PathBuf>) = match (&dir, &a.out) {
            (Some(d), _) => {
                let p = d.join(format!("{}.csv", topic.trim_start_matches('/').replace('/', "_")));
                (Box::new(std::io::BufWriter::new(create(&p)?)), Some(p))
            }
            (None, Some(p)) if p.as_os_str() != "-" => (Box::new(std::io::BufWriter::new(create(p)?)), Some(p.clone())),
            _ => (Box::new(std::io::BufWriter::new(std::io::stdout())), None),
        };
        let mut columns = vec!["log_time_ns", "publish_time_ns", "sequence", "crc_ok", "decode_error"]
            .into_iter()
            .map(String::from)
            .collect::<Vec<_>>();
        if let Some(kind) = kind_of(ty) {
            columns.extend(column_names(kind));
        } else {
            columns.push("cdr_hex".into());
        }
        let mut t = Table { out, columns, rows: 0 };
        writeln!(t.out, "{}", t.columns.iter().map(|c| csv_field(c)).collect::<Vec<_>>().join(","))?;
        if let Some(p) = path {
            eprintln!("{topic} -> {}", p.display());
        }
        tables.insert(topic.clone(), t);
    }
    for m in recording::messages(&bytes).with_context(|| format!("reading {}", a.file.display()))? {
        let m = m.with_context(|| format!("reading {}", a.file.display()))?;
        let Some(t) = tables.get_mut(&m.channel.topic) else {
            continue;
        };
        let ty = topics.get(&m.channel.topic).cloned().unwrap_or_default();
        let mut row = vec![m.log_time.to_string(), m.publish_time.to_string(), m.sequence.to_string()];
        match kind_of(&ty) {
            Some(kind) => match decode_flat(kind, &m.data) {
                Ok((cols, crc)) => {
                    row.push(crc.map_or(String::new(), |c| c.to_string()));
                    row.push(String::new());
                    row.extend(cols.into_iter().map(|(_, v)| v));
                }
                Err(e) => {
                    row.push(String::new());
                    row.push(e.to_string());
                    row.resize(t.columns.len(), String::new());
                }
            },
            None => {
                row.push(String::new());
                row.push(String::new());
                row.push(m.data.iter().map(|b| format!("{b:02x}")).collect());
            }
        }
        writeln!(t.out, "{}", row.iter().map(|c| csv_field(c)).collect::<Vec<_>>().join(","))?;
        t.rows += 1;
    }
    for (topic, t) in tables.iter_mut() {
        t.out.flush()?;
        eprintln!("{topic}: {} rows", t.rows);
    }
    Ok(Exit::Success)
}

fn create(p: &Path) -> Result<std::fs::File> {
    std::fs::File::create(p).with_context(|| format!("creating {}", p.display()))
}

fn info(file: &Path) -> Result<Exit> {
    let bytes = std::fs::read(file).with_context(|| format!("reading {}", file.display()))?;
    let mut stats: BTreeMap<String, (String, String, u64, u64, u64)> = BTreeMap::new();
    for m in recording::messages(&bytes).with_context(|| format!("reading {}", file.display()))? {
        let m = m.with_context(|| format!("reading {}", file.display()))?;
        let ty = channel_type_name(&m.channel).unwrap_or_default();
        let e = stats
            .entry(m.channel.topic.clone())
            .or_insert_with(|| (ty, m.channel.message_encoding.clone(), 0, u64::MAX, 0));
        e.2 += 1;
        e.3 = e.3.min(m.log_time);
        e.4 = e.4.max(m.log_time);
    }
    for (topic, (ty, enc, n, t0, t1)) in &stats {
        let span = t1.saturating_sub(*t0) as f64 / 1e9;
        println!("{topic}\t{ty}\t{enc}\t{n} messages\t{span:.2} s");
    }
    Ok(Exit::Success)
}
