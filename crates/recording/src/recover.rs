//! Recovering an unfinished recording (issue 19): a recorder killed with `kill -9` or by a power cut leaves a file
//! without its summary and footer, and its last chunk cut off. [`recover`] copies every message that can be read
//! (every chunk written before the crash) into a finished MCAP file with the same channels and schemas, and says
//! how the input ended. At most the chunk being filled when the recorder died is lost: `chunk_size` bytes of
//! messages (see [`crate::write_options_with_chunk_size`]), plus what the recorder's output buffer held.
use crate::read::{messages, ReadError};
use std::io::{Seek, Write};

/// Why a recovery failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RecoverError {
    /// The input cannot be read at all (not MCAP).
    #[error(transparent)]
    Read(#[from] ReadError),
    /// Writing the recovered file failed.
    #[error("writing the recovered file")]
    Write(#[source] mcap::McapError),
}

/// What a recovery found and wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Recovered {
    /// Messages copied.
    pub messages: usize,
    /// How the input ended: `None` when it was read to its end (a finished file), else the reason reading stopped
    /// (a truncated last record, a corrupt chunk).
    pub stopped_by: Option<String>,
}

/// Copies the readable messages of the MCAP file in `bytes` into a finished MCAP file written to `out` with
/// `options` (its channels and schemas are the input's, registered as their first message is copied).
pub fn recover<W: Write + Seek>(bytes: &[u8], out: W, options: mcap::WriteOptions) -> Result<Recovered, RecoverError> {
    let mut stream = messages(bytes)?;
    let mut writer = options.create(out).map_err(RecoverError::Write)?;
    let mut copied = 0usize;
    let mut stopped_by = None;
    for m in stream.by_ref() {
        match m {
            Ok(m) => {
                writer.write(&m).map_err(RecoverError::Write)?;
                copied += 1;
            }
            Err(ReadError::NotMcap(e)) => return Err(ReadError::NotMcap(e).into()),
            Err(e) => {
                stopped_by = Some(e.to_string());
                break;
            }
        }
    }
    writer.finish().map_err(RecoverError::Write)?;
    Ok(Recovered { messages: copied, stopped_by })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{add_topic, write_options_with_chunk_size, Compression};
    use std::io::Cursor;

    /// A finished recording of `n` messages on one topic, in chunks of `chunk` bytes.
    fn recording(n: u32, chunk: u64) -> Vec<u8> {
        let mut buf = Cursor::new(Vec::new());
        let mut w = write_options_with_chunk_size("test", Compression::None, chunk).create(&mut buf).expect("writer");
        let ch = add_topic(&mut w, "rt/lowstate", "unitree_hg::msg::dds_::LowState_").expect("channel");
        for i in 0..n {
            let header = mcap::records::MessageHeader {
                channel_id: ch,
                sequence: i,
                log_time: u64::from(i),
                publish_time: u64::from(i),
            };
            w.write_to_known_channel(&header, &[0u8; 100]).expect("message");
        }
        w.finish().expect("finish");
        drop(w);
        buf.into_inner()
    }

    fn count(bytes: &[u8]) -> (usize, Option<ReadError>) {
        let mut n = 0;
        for m in messages(bytes).expect("mcap") {
            match m {
                Ok(_) => n += 1,
                Err(e) => return (n, Some(e)),
            }
        }
        (n, None)
    }

    #[test]
    fn a_finished_file_is_copied_whole_and_a_cut_one_up_to_its_last_whole_chunk() {
        let full = recording(1000, 10_000);
        let mut out = Cursor::new(Vec::new());
        let r = recover(&full, &mut out, crate::write_options("test", Compression::None)).expect("recover");
        assert_eq!(r, Recovered { messages: 1000, stopped_by: None });
        assert_eq!(count(&out.into_inner()).0, 1000);

        // Cut in the middle, as a killed recorder leaves it: everything before the cut chunk comes back, and the
        // copy is a finished file (it reads to its end without error).
        let cut = &full[..full.len() / 2];
        let (readable, err) = count(cut);
        assert!(matches!(err, Some(ReadError::Truncated { .. })), "{err:?}");
        let mut out = Cursor::new(Vec::new());
        let r = recover(cut, &mut out, crate::write_options("test", Compression::None)).expect("recover");
        assert_eq!(r.messages, readable);
        assert!(r.stopped_by.as_deref().is_some_and(|s| s.contains("truncated")), "{r:?}");
        let copy = out.into_inner();
        let (n, err) = count(&copy);
        assert!(n == readable && err.is_none(), "{n} of {readable}: {err:?}");
        // At most one chunk (10 000 bytes of ~130-byte message records, about 77 messages) is lost before the cut.
        let lost_before_cut = 1000 * (full.len() / 2) / full.len() - readable;
        assert!(
            lost_before_cut <= 80,
            "{readable} readable of about {} before the cut",
            1000 * (full.len() / 2) / full.len()
        );
    }

    #[test]
    fn not_mcap_is_a_typed_error() {
        let mut out = Cursor::new(Vec::new());
        let e = recover(b"hello", &mut out, crate::write_options("test", Compression::None));
        assert!(matches!(e, Err(RecoverError::Read(ReadError::NotMcap(_)))), "{e:?}");
    }
}
