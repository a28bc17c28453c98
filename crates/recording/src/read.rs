//! Reading a recording: the one MCAP message reader of the project (`ulab gap`, `ulab replay`, `ulab log`, the
//! benchmarks). It reads chunked files compressed with zstd or lz4 (the default of the official Python and C++
//! writers, the `mcap` CLI and Foxglove), uncompressed chunks, and unchunked files, and turns every failure into a
//! [`ReadError`] that says what is wrong with the file.

/// Chunk compressions this build reads (and [`crate::Compression`] writes).
pub const READABLE_COMPRESSIONS: &str = "none, zstd, lz4";

/// Why a recording could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The bytes do not start with the MCAP magic.
    #[error("not an MCAP file (no MCAP magic at the start)")]
    NotMcap(#[source] mcap::McapError),
    /// A chunk uses a compression this build has no decoder for.
    #[error("a chunk is compressed with {0:?}, which ulab cannot read (it reads {READABLE_COMPRESSIONS})")]
    UnsupportedCompression(String),
    /// The file ends in the middle of a record (e.g. a recorder killed before it finished the file, which leaves
    /// the chunk it was filling with a placeholder length).
    #[error("the MCAP file is truncated: it ends in the middle of a record after {messages} messages")]
    Truncated {
        messages: usize,
        #[source]
        source: mcap::McapError,
    },
    /// A record, a chunk's compressed stream or a CRC is wrong.
    #[error("the MCAP file is corrupt after {messages} messages")]
    Corrupt {
        messages: usize,
        #[source]
        source: mcap::McapError,
    },
}

impl ReadError {
    /// `finished`: the file ends with the MCAP magic (its footer was written).
    fn from_mcap(e: mcap::McapError, messages: usize, finished: bool) -> Self {
        match e {
            mcap::McapError::BadMagic if messages == 0 => ReadError::NotMcap(e),
            mcap::McapError::UnsupportedCompression(c) => ReadError::UnsupportedCompression(c),
            mcap::McapError::UnexpectedEof => ReadError::Truncated { messages, source: e },
            // The `mcap` writer streams a chunk into the file with a placeholder length (u64::MAX) and patches it
            // when the chunk is complete: a file without its footer that ends inside such a chunk was cut off while
            // recording, not corrupted.
            mcap::McapError::UnexpectedEoc | mcap::McapError::RecordTooLarge { len: u64::MAX, .. } if !finished => {
                ReadError::Truncated { messages, source: e }
            }
            e => ReadError::Corrupt { messages, source: e },
        }
    }
}

/// Largest record (bytes) the reader accepts, whatever a (possibly corrupt) length field says: the file's size or
/// 256 MiB, whichever is larger (a compressed chunk may hold more than the file's size; a recording's chunks hold a
/// few MiB). `mcap::MessageStream` has no such limit and allocates whatever a corrupt length inside a decompressed
/// chunk says (found by `tests/it/official_writer.rs`: a capacity-overflow panic).
pub const MIN_RECORD_LIMIT: usize = 256 << 20;

/// The messages of an MCAP file in file order, each with its channel; ends after the first error.
pub struct Messages<'a> {
    inner: Option<mcap::io::MessageReader<&'a [u8]>>,
    read: usize,
    /// The file ends with the MCAP magic (a finished file).
    finished: bool,
}

impl std::fmt::Debug for Messages<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Messages").field("read", &self.read).field("done", &self.inner.is_none()).finish()
    }
}

impl<'a> Iterator for Messages<'a> {
    type Item = Result<mcap::Message<'static>, ReadError>;

    fn next(&mut self) -> Option<Self::Item> {
        let item = self.inner.as_mut()?.next()?;
        match item {
            Ok(m) => {
                self.read += 1;
                Some(Ok(m))
            }
            Err(e) => {
                // The stream may keep failing on the same bytes: one error ends the iteration.
                self.inner = None;
                Some(Err(ReadError::from_mcap(e, self.read, self.finished)))
            }
        }
    }
}

/// Reads the messages of the MCAP file in `bytes`. Each chunk's CRC (when its writer stored one) is checked before
/// any of its records is used, so a corrupt compressed chunk is an error rather than garbage messages.
pub fn messages(bytes: &[u8]) -> Result<Messages<'_>, ReadError> {
    if !bytes.starts_with(mcap::MAGIC) {
        return Err(ReadError::NotMcap(mcap::McapError::BadMagic));
    }
    let options = mcap::sans_io::LinearReaderOptions::default()
        .with_record_length_limit(bytes.len().max(MIN_RECORD_LIMIT))
        .with_validate_chunk_crcs(true)
        .with_prevalidate_chunk_crcs(true);
    let finished = bytes.len() >= 2 * mcap::MAGIC.len() && bytes.ends_with(mcap::MAGIC);
    Ok(Messages { inner: Some(mcap::io::MessageReader::new_with_options(bytes, options)), read: 0, finished })
}
