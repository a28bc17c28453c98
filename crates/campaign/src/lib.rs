//! Campaigns beyond one machine (issue 62). A campaign is a fixed list of independent items (episodes, grid cells,
//! trials, search lanes) numbered `0..total` in the order the unsharded run computes them. `--shard K/N` runs the
//! items dealt to shard K and writes their results into a shard file ([`write`]); [`merge`] checks that a set of
//! shard files is one complete campaign and returns every result in item order, so that the analysis after it sees
//! exactly the results, in exactly the order, of the unsharded run.
//!
//! - The dealing rule: item `i` belongs to shard `i mod N + 1` (round robin, so that neighbouring items, which
//!   tend to cost about the same, land on different shards).
//! - The shard file, `shard-K-of-N.cbor`: format version, campaign kind, producer, the shard, the item count, the
//!   campaign's configuration and the shard's (item, result) pairs. CBOR, because results must come back bit for
//!   bit: it stores every f64 exactly, NaN and infinities included, where JSON writes NaN as `null` and
//!   serde_json's default parser may miss the last bit of a decimal.
#![forbid(unsafe_code)]

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// Version of the shard file layout.
pub const FORMAT_VERSION: u32 = 1;

/// Shard `index` of `count` (1-based: `1/3`, `2/3`, `3/3`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "ShardRepr", into = "ShardRepr")]
pub struct Shard {
    index: u32,
    count: u32,
}

/// The stored form of a [`Shard`], checked on the way in.
#[derive(Serialize, Deserialize)]
struct ShardRepr {
    index: u32,
    count: u32,
}

impl TryFrom<ShardRepr> for Shard {
    type Error = ShardSpecError;
    fn try_from(r: ShardRepr) -> Result<Self, Self::Error> {
        Shard::new(r.index, r.count)
    }
}

impl From<Shard> for ShardRepr {
    fn from(s: Shard) -> Self {
        ShardRepr { index: s.index, count: s.count }
    }
}

/// A `--shard` value that is not `K/N` with `1 <= K <= N`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ShardSpecError {
    #[error("shard `{0}` is not K/N (two whole numbers, e.g. 2/3)")]
    Syntax(String),
    #[error("shard {index}/{count}: shards are numbered from 1, and there is at least one")]
    Zero { index: u32, count: u32 },
    #[error("shard {index}/{count}: there are only {count} shards")]
    OutOfRange { index: u32, count: u32 },
}

impl Shard {
    /// The whole campaign as one shard.
    pub const WHOLE: Shard = Shard { index: 1, count: 1 };

    /// Shard `index` of `count`, `1 <= index <= count`.
    pub fn new(index: u32, count: u32) -> Result<Shard, ShardSpecError> {
        if index == 0 || count == 0 {
            Err(ShardSpecError::Zero { index, count })
        } else if index > count {
            Err(ShardSpecError::OutOfRange { index, count })
        } else {
            Ok(Shard { index, count })
        }
    }

    /// K, from 1.
    pub fn index(self) -> u32 {
        self.index
    }

    /// N.
    pub fn count(self) -> u32 {
        self.count
    }

    /// Whether item `item` (from 0) is dealt to this shard: the dealing rule.
    pub fn owns(self, item: usize) -> bool {
        item % self.count as usize == (self.index - 1) as usize
    }

    /// The items of a campaign of `total` items dealt to this shard, ascending.
    pub fn items(self, total: usize) -> impl Iterator<Item = usize> {
        // `count >= 1` by construction, so the step is never 0.
        ((self.index - 1) as usize..total).step_by(self.count as usize)
    }

    /// The file a shard's results go to: `shard-K-of-N.cbor`.
    pub fn file_name(self) -> String {
        format!("shard-{}-of-{}.cbor", self.index, self.count)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = ShardSpecError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let syntax = || ShardSpecError::Syntax(s.to_owned());
        let (k, n) = s.trim().split_once('/').ok_or_else(syntax)?;
        let k: u32 = k.trim().parse().map_err(|_| syntax())?;
        let n: u32 = n.trim().parse().map_err(|_| syntax())?;
        Shard::new(k, n)
    }
}

/// One shard's results. `C` is the campaign's configuration (everything that decides the results, so that shards
/// of different campaigns are told apart); `T` one item's result.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ShardFile<C, T> {
    /// [`FORMAT_VERSION`].
    pub format: u32,
    /// Which campaign (`diff`, `validate`, ...): what `ulab merge` dispatches on.
    pub kind: String,
    /// The program and version that computed the results; shards of different versions are not merged.
    pub producer: String,
    pub shard: Shard,
    /// Items of the whole campaign.
    pub total: usize,
    pub config: C,
    /// (item, result), ascending by item: exactly the items the dealing rule gives this shard.
    pub items: Vec<(usize, T)>,
}

/// What every shard file starts with, read without knowing the configuration and result types.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
pub struct Header {
    pub format: u32,
    pub kind: String,
    pub producer: String,
    pub shard: Shard,
    pub total: usize,
}

/// Reading, writing and merging shard files.
#[derive(Debug, thiserror::Error)]
pub enum ShardError {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}: writing CBOR")]
    Encode { path: PathBuf, source: ciborium::ser::Error<std::io::Error> },
    #[error("{path}: not a readable shard file")]
    Decode { path: PathBuf, source: ciborium::de::Error<std::io::Error> },
    #[error("{path}: shard file format {found}, this program reads format {FORMAT_VERSION}")]
    Format { path: PathBuf, found: u32 },
    #[error("no shard file (shard-K-of-N.cbor) in {0}")]
    NoShardFiles(PathBuf),
    #[error("no shard files given")]
    Empty,
    #[error("{path}: a `{found}` shard, expected `{expected}`")]
    KindMismatch { path: PathBuf, expected: String, found: String },
    #[error("{path}: computed by {found}, the first shard by {expected}; merge shards of one program version")]
    ProducerMismatch { path: PathBuf, expected: String, found: String },
    #[error("{path}: shard of {found}, the first shard is of {expected}")]
    CountMismatch { path: PathBuf, expected: u32, found: u32 },
    #[error("{path}: a campaign of {found} items, the first shard's has {expected}")]
    TotalMismatch { path: PathBuf, expected: usize, found: usize },
    #[error("{path}: a different campaign configuration from {first}'s")]
    ConfigMismatch { path: PathBuf, first: PathBuf },
    #[error("shard {shard} given twice: {first} and {second}")]
    DuplicateShard { shard: Shard, first: PathBuf, second: PathBuf },
    #[error("shard(s) {missing:?} of {count} missing")]
    MissingShards { missing: Vec<u32>, count: u32 },
    #[error("{path}: its items are not the ones dealt to shard {shard}")]
    WrongItems { path: PathBuf, shard: Shard },
}

/// Writes `file` as `dir/shard-K-of-N.cbor` (creating `dir`); returns the path.
pub fn write<C: Serialize, T: Serialize>(dir: &Path, file: &ShardFile<C, T>) -> Result<PathBuf, ShardError> {
    std::fs::create_dir_all(dir).map_err(|source| ShardError::Io { path: dir.to_owned(), source })?;
    let path = dir.join(file.shard.file_name());
    let io = |source| ShardError::Io { path: path.clone(), source };
    let f = std::fs::File::create(&path).map_err(io)?;
    let mut w = std::io::BufWriter::new(f);
    ciborium::into_writer(file, &mut w).map_err(|source| ShardError::Encode { path: path.clone(), source })?;
    std::io::Write::flush(&mut w).map_err(io)?;
    Ok(path)
}

fn decode<X: DeserializeOwned>(path: &Path) -> Result<X, ShardError> {
    let f = std::fs::File::open(path).map_err(|source| ShardError::Io { path: path.to_owned(), source })?;
    ciborium::from_reader(std::io::BufReader::new(f))
        .map_err(|source| ShardError::Decode { path: path.to_owned(), source })
}

/// The header of a shard file (its format checked).
pub fn read_header(path: &Path) -> Result<Header, ShardError> {
    let h: Header = decode(path)?;
    if h.format != FORMAT_VERSION {
        return Err(ShardError::Format { path: path.to_owned(), found: h.format });
    }
    Ok(h)
}

/// A shard file of campaign kind `kind`.
pub fn read<C: DeserializeOwned, T: DeserializeOwned>(path: &Path, kind: &str) -> Result<ShardFile<C, T>, ShardError> {
    let h = read_header(path)?;
    if h.kind != kind {
        return Err(ShardError::KindMismatch { path: path.to_owned(), expected: kind.to_owned(), found: h.kind });
    }
    decode(path)
}

/// The shard files named by `paths`: a file as given, a directory's `shard-K-of-N.cbor` files in name order.
pub fn find(paths: &[PathBuf]) -> Result<Vec<PathBuf>, ShardError> {
    let mut out = Vec::new();
    for p in paths {
        if !p.is_dir() {
            out.push(p.clone());
            continue;
        }
        let io = |source| ShardError::Io { path: p.clone(), source };
        let mut found = Vec::new();
        for e in std::fs::read_dir(p).map_err(io)? {
            let path = e.map_err(io)?.path();
            let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
            if name.starts_with("shard-") && name.ends_with(".cbor") {
                found.push(path);
            }
        }
        if found.is_empty() {
            return Err(ShardError::NoShardFiles(p.clone()));
        }
        found.sort();
        out.extend(found);
    }
    if out.is_empty() {
        return Err(ShardError::Empty);
    }
    Ok(out)
}

/// Checks that `files` (path, content) are every shard of one campaign, once each, and returns its configuration
/// and every item's result in item order.
pub fn merge<C: PartialEq, T>(files: Vec<(PathBuf, ShardFile<C, T>)>) -> Result<(C, Vec<T>), ShardError> {
    let (first_path, first) = files.first().ok_or(ShardError::Empty)?;
    let (count, total) = (first.shard.count, first.total);
    for (path, f) in &files[1..] {
        let path = path.clone();
        if f.kind != first.kind {
            return Err(ShardError::KindMismatch { path, expected: first.kind.clone(), found: f.kind.clone() });
        }
        if f.producer != first.producer {
            return Err(ShardError::ProducerMismatch {
                path,
                expected: first.producer.clone(),
                found: f.producer.clone(),
            });
        }
        if f.shard.count != count {
            return Err(ShardError::CountMismatch { path, expected: count, found: f.shard.count });
        }
        if f.total != total {
            return Err(ShardError::TotalMismatch { path, expected: total, found: f.total });
        }
        if f.config != first.config {
            return Err(ShardError::ConfigMismatch { path, first: first_path.clone() });
        }
    }
    let mut seen: Vec<Option<PathBuf>> = vec![None; count as usize];
    let mut slots: Vec<Option<T>> = std::iter::repeat_with(|| None).take(total).collect();
    let mut config = None;
    for (path, f) in files {
        // `index` is in 1..=count (checked when the shard was made or read).
        let k = f.shard.index as usize - 1;
        if let Some(prev) = &seen[k] {
            return Err(ShardError::DuplicateShard { shard: f.shard, first: prev.clone(), second: path });
        }
        if !f.items.iter().map(|(i, _)| *i).eq(f.shard.items(total)) {
            return Err(ShardError::WrongItems { path, shard: f.shard });
        }
        for (i, t) in f.items {
            slots[i] = Some(t);
        }
        seen[k] = Some(path);
        config.get_or_insert(f.config);
    }
    let missing: Vec<u32> = (1..=count).filter(|k| seen[*k as usize - 1].is_none()).collect();
    if !missing.is_empty() {
        return Err(ShardError::MissingShards { missing, count });
    }
    // Every shard present with exactly its dealt items: every slot is filled.
    let items: Option<Vec<T>> = slots.into_iter().collect();
    match (config, items) {
        (Some(c), Some(items)) => Ok((c, items)),
        _ => Err(ShardError::MissingShards { missing: vec![], count }),
    }
}
