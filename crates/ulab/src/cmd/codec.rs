//! `ulab codec decode|encode|crc|validate`: the byte-level contract scripts rely on.

use crate::exit::Exit;
use anyhow::{bail, Context, Result};
use clap::{Subcommand, ValueEnum};
use lowlevel_codec::{cdr, crc, json, validate, Encoding, Endianness, Representation};
use std::io::{Read, Write};
use unitree_idl::{with_message_type, IdlStruct, MessageType};

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    action: Action,
}

#[derive(Debug, Subcommand)]
enum Action {
    /// Read CDR bytes (with encapsulation header) on stdin, print the JSON document.
    Decode {
        /// Message type, e.g. hg/LowCmd, hg/LowState, go/LowCmd, hg/HandCmd.
        #[arg(long = "type", value_name = "T")]
        ty: MessageType,
    },
    /// Read a JSON document on stdin (only `value` is required), write CDR bytes to stdout.
    Encode {
        #[arg(long = "type", value_name = "T")]
        ty: MessageType,
        /// Overrides the document's representation (default xcdr1).
        #[arg(long, value_enum)]
        representation: Option<ReprArg>,
        /// Big-endian payload (overrides the document's endianness; default little).
        #[arg(long)]
        big_endian: bool,
    },
    /// Read a JSON document on stdin, print Unitree's CRC of its `value` as a decimal u32.
    Crc {
        #[arg(long = "type", value_name = "T")]
        ty: MessageType,
    },
    /// Read CDR bytes on stdin and list what makes the message unsafe to apply: non-finite
    /// values, targets and gains beyond the robot's limits, unused slots not zero, a bad CRC.
    /// Exit 0 when there is nothing to report, 1 otherwise.
    Validate {
        #[arg(long = "type", value_name = "T")]
        ty: MessageType,
        /// Robot whose limits apply to hg/LowCmd (only h1_2 is built in).
        #[arg(long, default_value = "h1_2", value_parser = ["h1_2"])]
        robot: String,
    },
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum ReprArg {
    Xcdr1,
    Xcdr2,
}

pub fn run(args: Args) -> Result<Exit> {
    match args.action {
        Action::Decode { ty } => {
            let bytes = read_stdin_bytes()?;
            let text = with_message_type!(ty, T => decode_to_json::<T>(ty, &bytes))?;
            std::io::stdout().write_all(text.as_bytes()).context("writing to stdout")?;
        }
        Action::Encode { ty, representation, big_endian } => {
            let text = read_stdin_text()?;
            let bytes = with_message_type!(ty, T => encode_from_json::<T>(ty, &text, representation, big_endian))?;
            std::io::stdout().write_all(&bytes).context("writing to stdout")?;
        }
        Action::Crc { ty } => {
            let text = read_stdin_text()?;
            let value = with_message_type!(ty, T => crc_from_json::<T>(ty, &text))?;
            println!("{value}");
        }
        Action::Validate { ty, robot: _ } => {
            let bytes = read_stdin_bytes()?;
            let findings = with_message_type!(ty, T => validate_bytes::<T>(ty, &bytes))?;
            for line in &findings {
                println!("{line}");
            }
            if !findings.is_empty() {
                return Ok(Exit::Failed);
            }
            println!("ok: no findings");
        }
    }
    Ok(Exit::Success)
}

/// Findings as `name: description` lines, CRC first.
fn validate_bytes<T: IdlStruct>(ty: MessageType, bytes: &[u8]) -> Result<Vec<String>> {
    let value = cdr::decode::<T>(bytes).with_context(|| format!("decoding {} bytes as {ty}", bytes.len()))?.value;
    let mut lines = Vec::new();
    if crc::check_any(&value) == Some(false) {
        lines.push("bad_crc: the stored crc does not match the message".to_owned());
    }
    let findings = validate::any(&value);
    lines.extend(findings.iter().map(|f| format!("{}: {f}", f.name())));
    Ok(lines)
}

fn decode_to_json<T: IdlStruct>(ty: MessageType, bytes: &[u8]) -> Result<String> {
    let decoded = cdr::decode::<T>(bytes).with_context(|| format!("decoding {} bytes as {ty}", bytes.len()))?;
    let crc_ok = crc::check_any(&decoded.value);
    Ok(json::document_to_json(ty, &decoded.value, decoded.encoding, crc_ok))
}

fn encode_from_json<T: IdlStruct>(
    ty: MessageType,
    text: &str,
    repr: Option<ReprArg>,
    big_endian: bool,
) -> Result<Vec<u8>> {
    let doc = json::document_from_json::<T>(ty, text).with_context(|| format!("reading a {ty} document"))?;
    let representation = match repr {
        Some(ReprArg::Xcdr1) => Representation::Xcdr1,
        Some(ReprArg::Xcdr2) => Representation::Xcdr2,
        None => doc.representation.unwrap_or(Representation::Xcdr1),
    };
    let endianness = if big_endian { Endianness::Big } else { doc.endianness.unwrap_or(Endianness::Little) };
    Ok(cdr::encode(&doc.value, Encoding { representation, endianness }))
}

fn crc_from_json<T: IdlStruct>(ty: MessageType, text: &str) -> Result<u32> {
    let doc = json::document_from_json::<T>(ty, text).with_context(|| format!("reading a {ty} document"))?;
    match crc::compute_any(&doc.value) {
        Some(value) => Ok(value),
        None => bail!("{ty} carries no CRC; only hg/LowCmd, hg/LowState, go/LowCmd and go/LowState do"),
    }
}

fn read_stdin_bytes() -> Result<Vec<u8>> {
    let mut bytes = Vec::new();
    std::io::stdin().read_to_end(&mut bytes).context("reading stdin")?;
    Ok(bytes)
}

fn read_stdin_text() -> Result<String> {
    let bytes = read_stdin_bytes()?;
    String::from_utf8(bytes).context("stdin is not UTF-8 text")
}
