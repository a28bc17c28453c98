//! Pieces shared by `ulab record`, `ulab replay` and `ulab log`: which topics carry which types,
//! the DDS network options, the OMG IDL text stored as MCAP schema, and flattening a decoded
//! message into named columns.

use anyhow::{bail, Context, Result};
use dds_transport::{DomainConfig, TopicSpec};
use unitree_idl::{with_message_type, Field, IdlStruct, MessageType, PrimKind, Primitive, Visitor};

/// MCAP metadata key holding the DDS type name of a channel.
pub const DDS_TYPE_KEY: &str = "dds_type_name";

/// Network options common to the DDS subcommands.
#[derive(Debug, Clone, clap::Args)]
pub struct NetArgs {
    /// DDS domain id (0 is the real robot's and needs --allow-robot).
    #[arg(long, default_value_t = dds_transport::config::DEFAULT_DOMAIN)]
    pub domain: u32,
    /// Network interface (anything but loopback needs --allow-robot).
    #[arg(long, default_value = dds_transport::config::DEFAULT_INTERFACE)]
    pub interface: String,
    /// Permit domain 0 and non-loopback interfaces, where a real robot may be.
    #[arg(long)]
    pub allow_robot: bool,
}

impl NetArgs {
    /// The transport configuration, with the safety rule checked.
    pub fn domain_config(&self) -> Result<DomainConfig> {
        let cfg = DomainConfig::loopback(self.domain)
            .interface(self.interface.clone())
            .allow_robot(self.allow_robot);
        match cfg.validate() {
            Ok(()) => Ok(cfg),
            Err(e @ dds_transport::Error::RobotNotAllowed { .. }) => {
                Err(anyhow::Error::new(e)
                    .context("network settings refused (pass --allow-robot to reach a real robot)"))
            }
            Err(e) => Err(anyhow::Error::new(e).context("invalid network settings")),
        }
    }
}

/// A topic to record: DDS topic name and type (known to the codec, or only a DDS type name).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicChoice {
    pub spec: TopicSpec,
    pub kind: Option<MessageType>,
}

/// Parses `TOPIC=TYPE` (TYPE a short name like `hg/LowState` or a DDS type name) or a bare
/// `rt/lowcmd` / `rt/lowstate`, whose type follows `family` (`hg` or `go`).
pub fn parse_topic(text: &str, family: &str) -> Result<TopicChoice> {
    let (name, ty) = match text.split_once('=') {
        Some((n, t)) => (n.trim(), t.trim().to_owned()),
        None => {
            let short = match text.trim() {
                "rt/lowcmd" => "LowCmd",
                "rt/lowstate" => "LowState",
                other => {
                    bail!("topic {other:?} needs a type: write it as {other}=hg/LowState or {other}=<DDS type name>")
                }
            };
            (text.trim(), format!("{family}/{short}"))
        }
    };
    if name.is_empty() || ty.is_empty() {
        bail!("bad topic {text:?}: expected TOPIC=TYPE");
    }
    match MessageType::from_name(&ty) {
        Ok(kind) => Ok(TopicChoice {
            spec: TopicSpec::new(name, kind.dds_type_name()),
            kind: Some(kind),
        }),
        Err(_) if ty.contains("::") => Ok(TopicChoice {
            spec: TopicSpec::new(name, ty),
            kind: None,
        }),
        Err(e) => Err(e).with_context(|| format!("topic {name:?}")),
    }
}

/// The codec's type for a DDS type name, if it knows it.
pub fn kind_of(dds_type_name: &str) -> Option<MessageType> {
    MessageType::ALL
        .iter()
        .copied()
        .find(|k| k.dds_type_name() == dds_type_name)
}

// ---------------------------------------------------------------------------------------------
// OMG IDL text from the reflection in unitree-idl.

fn idl_prim(kind: PrimKind) -> &'static str {
    match kind {
        PrimKind::U8 => "uint8",
        PrimKind::I16 => "int16",
        PrimKind::U16 => "uint16",
        PrimKind::I32 => "int32",
        PrimKind::U32 => "uint32",
        PrimKind::F32 => "float",
    }
}

fn qualified(dds_type_name: &str) -> String {
    format!("::{dds_type_name}")
}

struct IdlGen {
    /// (DDS type name, member lines), dependencies first.
    structs: Vec<(&'static str, Vec<String>)>,
}

impl IdlGen {
    fn add<S: IdlStruct>(&mut self) {
        if self.structs.iter().any(|(n, _)| *n == S::DDS_TYPE_NAME) {
            return;
        }
        let mut m = Members {
            gen: self,
            lines: Vec::new(),
        };
        S::zeroed().walk(&mut m);
        let lines = m.lines;
        self.structs.push((S::DDS_TYPE_NAME, lines));
    }
}

struct Members<'a> {
    gen: &'a mut IdlGen,
    lines: Vec<String>,
}

impl Visitor for Members<'_> {
    fn primitive<P: Primitive>(&mut self, name: &'static str, _value: &P) {
        self.lines.push(format!("{} {name};", idl_prim(P::KIND)));
    }
    fn primitive_array<P: Primitive>(&mut self, name: &'static str, items: &[P]) {
        self.lines
            .push(format!("{} {name}[{}];", idl_prim(P::KIND), items.len()));
    }
    fn structure<S: IdlStruct>(&mut self, name: &'static str, _value: &S) {
        self.gen.add::<S>();
        self.lines.push(format!("{} {name};", qualified(S::DDS_TYPE_NAME)));
    }
    fn struct_array<S: IdlStruct>(&mut self, name: &'static str, items: &[S]) {
        self.gen.add::<S>();
        self.lines
            .push(format!("{} {name}[{}];", qualified(S::DDS_TYPE_NAME), items.len()));
    }
    fn struct_sequence<S: IdlStruct>(&mut self, name: &'static str, _items: &[S]) {
        self.gen.add::<S>();
        self.lines
            .push(format!("sequence<{}> {name};", qualified(S::DDS_TYPE_NAME)));
    }
}

/// OMG IDL text defining `kind` and everything it uses (MCAP schema encoding `omgidl`).
pub fn idl_text(kind: MessageType) -> String {
    let mut gen = IdlGen { structs: Vec::new() };
    with_message_type!(kind, T => gen.add::<T>());
    let mut out = format!(
        "// {} ({}), generated by ulab from unitree-idl\n",
        kind.dds_type_name(),
        kind.name()
    );
    for (name, lines) in &gen.structs {
        let mut parts: Vec<&str> = name.split("::").collect();
        let Some(sname) = parts.pop() else { continue };
        for (depth, m) in parts.iter().enumerate() {
            out.push_str(&format!("{}module {m} {{\n", "  ".repeat(depth)));
        }
        let ind = "  ".repeat(parts.len());
        out.push_str(&format!("{ind}@final\n{ind}struct {sname} {{\n"));
        for l in lines {
            out.push_str(&format!("{ind}  {l}\n"));
        }
        out.push_str(&format!("{ind}}};\n"));
        for depth in (0..parts.len()).rev() {
            out.push_str(&format!("{}}};\n", "  ".repeat(depth)));
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Flattening for CSV.

fn prim_text<P: Primitive>(v: &P) -> String {
    let bits = v.to_bits();
    match P::KIND {
        PrimKind::F32 => {
            let x = f32::from_bits(bits);
            if x.is_finite() {
                lowlevel_codec::json::float_text(x)
            } else if x.is_nan() {
                "NaN".to_owned()
            } else if x > 0.0 {
                "inf".to_owned()
            } else {
                "-inf".to_owned()
            }
        }
        PrimKind::I16 => (bits as u16 as i16).to_string(),
        PrimKind::I32 => (bits as i32).to_string(),
        PrimKind::U8 | PrimKind::U16 | PrimKind::U32 => bits.to_string(),
    }
}

/// Collects `(column name, value)` pairs: `motor_state[3].q`, `imu_state.rpy[2]`, ...
pub struct Flatten {
    prefix: String,
    pub columns: Columns,
}

impl Flatten {
    pub fn of<T: IdlStruct>(value: &T) -> Columns {
        let mut f = Flatten {
            prefix: String::new(),
            columns: Vec::new(),
        };
        value.walk(&mut f);
        f.columns
    }

    fn nested<S: IdlStruct>(&mut self, prefix: String, value: &S) {
        let saved = std::mem::replace(&mut self.prefix, prefix);
        value.walk(self);
        self.prefix = saved;
    }
}

impl Visitor for Flatten {
    fn primitive<P: Primitive>(&mut self, name: &'static str, value: &P) {
        self.columns.push((format!("{}{name}", self.prefix), prim_text(value)));
    }
    fn primitive_array<P: Primitive>(&mut self, name: &'static str, items: &[P]) {
        for (i, v) in items.iter().enumerate() {
            self.columns.push((format!("{}{name}[{i}]", self.prefix), prim_text(v)));
        }
    }
    fn structure<S: IdlStruct>(&mut self, name: &'static str, value: &S) {
        let p = format!("{}{name}.", self.prefix);
        self.nested(p, value);
    }
    fn struct_array<S: IdlStruct>(&mut self, name: &'static str, items: &[S]) {
        for (i, v) in items.iter().enumerate() {
            let p = format!("{}{name}[{i}].", self.prefix);
            self.nested(p, v);
        }
    }
    fn struct_sequence<S: IdlStruct>(&mut self, name: &'static str, items: &[S]) {
        self.struct_array(name, items);
    }
}

/// `(column name, value)` pairs of one message.
pub type Columns = Vec<(String, String)>;

/// Decodes a sample of `kind` and flattens it; also returns its CRC status where it has one.
/// The error is the codec's explanation of why the bytes do not decode.
pub fn decode_flat(kind: MessageType, bytes: &[u8]) -> Result<(Columns, Option<bool>), String> {
    with_message_type!(kind, T => {
        match lowlevel_codec::decode::<T>(bytes) {
            Ok(d) => Ok((Flatten::of(&d.value), lowlevel_codec::crc::check_any(&d.value))),
            Err(e) => Err(e.to_string()),
        }
    })
}

/// Column names of `kind` (from its zero value).
pub fn column_names(kind: MessageType) -> Vec<String> {
    with_message_type!(kind, T => Flatten::of(&<T as Field>::zeroed()).into_iter().map(|(n, _)| n).collect())
}

/// The `tick` of a LowState sample (hg or go), if it decodes.
pub fn lowstate_tick(kind: MessageType, bytes: &[u8]) -> Option<u32> {
    match kind {
        MessageType::HgLowState => lowlevel_codec::decode::<unitree_idl::hg::LowState_>(bytes)
            .ok()
            .map(|d| d.value.tick),
        MessageType::GoLowState => lowlevel_codec::decode::<unitree_idl::go::LowState_>(bytes)
            .ok()
            .map(|d| d.value.tick),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_topics() {
        let t = parse_topic("rt/lowstate", "hg").expect("parse");
        assert_eq!(t.spec.type_name, "unitree_hg::msg::dds_::LowState_");
        assert_eq!(t.kind, Some(MessageType::HgLowState));
        let t = parse_topic("rt/lowcmd", "go").expect("parse");
        assert_eq!(t.spec.type_name, "unitree_go::msg::dds_::LowCmd_");
        let t = parse_topic("rt/x=hg/HandCmd", "hg").expect("parse");
        assert_eq!(t.kind, Some(MessageType::HgHandCmd));
        let t = parse_topic("rt/y=foo::Bar_", "hg").expect("parse");
        assert_eq!((t.spec.type_name.as_str(), t.kind), ("foo::Bar_", None));
        assert!(parse_topic("rt/odd", "hg").is_err());
        assert!(parse_topic("rt/odd=nope", "hg").is_err());
    }

    #[test]
    fn idl_text_defines_nested_types_first() {
        let t = idl_text(MessageType::HgLowState);
        let imu = t.find("struct IMUState_").expect("imu");
        let motor = t.find("struct MotorState_").expect("motor");
        let low = t.find("struct LowState_").expect("low");
        assert!(imu < low && motor < low);
        assert!(t.contains("::unitree_hg::msg::dds_::MotorState_ motor_state[35];"));
        assert!(t.contains("uint8 wireless_remote[40];"));
    }

    #[test]
    fn columns_are_named() {
        let c = column_names(MessageType::HgLowCmd);
        assert_eq!(c[0], "mode_pr");
        assert!(c.contains(&"motor_cmd[34].kd".to_owned()));
        assert_eq!(c.last().map(String::as_str), Some("crc"));
    }
}
