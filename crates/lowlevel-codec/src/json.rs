//! JSON form of messages, as printed and read by `ulab codec`.
//!
//! A document is `{"type", "representation", "endianness", "crc_ok", "value"}`. In `value`,
//! members keep their IDL names, nested structs are objects, arrays and sequences are arrays.
//! Floats are printed as the shortest decimal that reads back as the same `f32` (so `-0.0`
//! stays `-0.0`); JSON has no non-finite numbers, so those are the strings `"NaN"`,
//! `"Infinity"` and `"-Infinity"`, and a NaN with a payload other than the canonical quiet NaN
//! is `"NaN:0x7fc00001"` (its bit pattern), so that every value round-trips bit for bit.
//! Booleans are JSON booleans, strings JSON strings, `int64` exact JSON integers.

use crate::cdr::{Encoding, Endianness, Representation};
use serde_json::{Map, Value};
use std::fmt::Write as _;
use unitree_idl::{IdlStruct, MessageType, PrimKind, Primitive, Visitor, VisitorMut};

pub use crate::text::float_text;
use crate::text::CANONICAL_NAN;

/// A parsed JSON document: the value plus whatever header fields it carried.
#[derive(Debug, Clone, PartialEq)]
pub struct Document<T> {
    /// The message, from the document's `value` member.
    pub value: T,
    /// The `representation` member, if present (`"xcdr1"` or `"xcdr2"`).
    pub representation: Option<Representation>,
    /// The `endianness` member, if present (`"little"` or `"big"`).
    pub endianness: Option<Endianness>,
}

/// Why a JSON text is not a valid message document.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum JsonError {
    /// The text is not JSON at all (the parser's message).
    #[error("not valid JSON: {0}")]
    Syntax(String),
    /// The document lacks the `value` member that holds the message.
    #[error("document has no `value` member")]
    MissingValue,
    /// The document's `type` names another message type.
    #[error("document is for type `{found}`, expected `{expected}`")]
    TypeMismatch {
        /// Short name of the type being parsed (`hg/LowCmd`).
        expected: &'static str,
        /// The document's `type` as written.
        found: String,
    },
    /// A header member (`representation`, `endianness`) with a value outside its set.
    #[error("`{field}`: `{found}` is not one of {allowed}")]
    BadHeaderField {
        /// Name of the header member.
        field: &'static str,
        /// Its value as written (JSON).
        found: String,
        /// The values it may take.
        allowed: &'static str,
    },
    /// A JSON value of the wrong kind (e.g. a string where a number or an array belongs).
    #[error("`{path}`: expected {expected}, found {found}")]
    WrongShape {
        /// Path of the member (`motor_cmd[3].q`; `value` for the whole message, empty for the document).
        path: String,
        /// What the member's IDL type needs.
        expected: String,
        /// What the document holds there.
        found: String,
    },
    /// A struct member absent from the document.
    #[error("`{path}`: missing member `{member}`")]
    MissingMember {
        /// Path of the struct that lacks it.
        path: String,
        /// IDL name of the missing member.
        member: &'static str,
    },
    /// A JSON member the IDL struct does not have.
    #[error("`{path}`: unknown member `{member}`")]
    UnknownMember {
        /// Path of the struct.
        path: String,
        /// The name found in the document.
        member: String,
    },
    /// A fixed array with the wrong number of elements.
    #[error("`{path}`: expected {expected} elements, found {found}")]
    WrongLength {
        /// Path of the array member.
        path: String,
        /// Its IDL length.
        expected: usize,
        /// Elements in the document.
        found: usize,
    },
    /// A number that the member's primitive type cannot represent.
    #[error("`{path}`: {value} does not fit in {kind}")]
    OutOfRange {
        /// Path of the member.
        path: String,
        /// The number as written.
        value: String,
        /// The primitive type it should fit in.
        kind: &'static str,
    },
}

/// Writes `value` as pretty JSON text (2-space indent; primitive arrays on one line).
pub fn value_to_json<T: IdlStruct>(value: &T) -> String {
    let mut w = JsonWriter { out: String::new(), indent: 0 };
    w.object(value);
    w.out
}

/// Writes a whole document for `value` as decoded with `encoding`.
pub fn document_to_json<T: IdlStruct>(
    kind: MessageType,
    value: &T,
    encoding: Encoding,
    crc_ok: Option<bool>,
) -> String {
    let crc = match crc_ok {
        Some(true) => "true",
        Some(false) => "false",
        None => "null",
    };
    let mut w = JsonWriter { out: String::new(), indent: 1 };
    w.object(value);
    format!(
        "{{\n  \"type\": \"{}\",\n  \"representation\": \"{}\",\n  \"endianness\": \"{}\",\n  \"crc_ok\": {},\n  \"value\": {}\n}}\n",
        kind.name(),
        encoding.representation.name(),
        encoding.endianness.name(),
        crc,
        w.out
    )
}

fn primitive_text<P: Primitive>(value: P) -> String {
    let bits = value.to_bits();
    match P::KIND {
        PrimKind::F32 => float_text(f32::from_bits(bits as u32)),
        PrimKind::Bool => (bits != 0).to_string(),
        PrimKind::I16 => (bits as u16 as i16).to_string(),
        PrimKind::I32 => (bits as u32 as i32).to_string(),
        PrimKind::I64 => (bits as i64).to_string(),
        PrimKind::U8 | PrimKind::U16 | PrimKind::U32 => bits.to_string(),
    }
}

struct JsonWriter {
    out: String,
    indent: usize,
}

impl JsonWriter {
    fn newline(&mut self) {
        self.out.push('\n');
        for _ in 0..self.indent {
            self.out.push_str("  ");
        }
    }
    fn key(&mut self, name: &str) {
        if !self.out.ends_with('{') && !self.out.ends_with('[') {
            self.out.push(',');
        }
        self.newline();
        let _ = write!(self.out, "\"{name}\": ");
    }
    fn object<S: IdlStruct>(&mut self, value: &S) {
        self.out.push('{');
        self.indent += 1;
        value.walk(self);
        self.indent -= 1;
        self.newline();
        self.out.push('}');
    }
    fn object_list<S: IdlStruct>(&mut self, items: &[S]) {
        if items.is_empty() {
            self.out.push_str("[]");
            return;
        }
        self.out.push('[');
        self.indent += 1;
        for (i, item) in items.iter().enumerate() {
            if i > 0 {
                self.out.push(',');
            }
            self.newline();
            self.object(item);
        }
        self.indent -= 1;
        self.newline();
        self.out.push(']');
    }
}

impl Visitor for JsonWriter {
    fn primitive<P: Primitive>(&mut self, name: &'static str, value: &P) {
        self.key(name);
        self.out.push_str(&primitive_text(*value));
    }
    fn primitive_array<P: Primitive>(&mut self, name: &'static str, items: &[P]) {
        self.key(name);
        self.out.push('[');
        for (i, item) in items.iter().enumerate() {
            if i > 0 {
                self.out.push_str(", ");
            }
            self.out.push_str(&primitive_text(*item));
        }
        self.out.push(']');
    }
    fn primitive_sequence<P: Primitive>(&mut self, name: &'static str, items: &[P]) {
        self.primitive_array(name, items);
    }
    fn string(&mut self, name: &'static str, value: &str) {
        self.key(name);
        self.out.push_str(&Value::String(value.to_owned()).to_string());
    }
    fn structure<S: IdlStruct>(&mut self, name: &'static str, value: &S) {
        self.key(name);
        self.object(value);
    }
    fn struct_array<S: IdlStruct>(&mut self, name: &'static str, items: &[S]) {
        self.key(name);
        self.object_list(items);
    }
    fn struct_sequence<S: IdlStruct>(&mut self, name: &'static str, items: &[S]) {
        self.key(name);
        self.object_list(items);
    }
}

/// Parses a document for type `T` (`kind` names it in errors). Only `value` is required; a
/// `type` member, when present, must name `kind`.
pub fn document_from_json<T: IdlStruct>(kind: MessageType, text: &str) -> Result<Document<T>, JsonError> {
    let doc: Value = serde_json::from_str(text).map_err(|e| JsonError::Syntax(e.to_string()))?;
    let Value::Object(doc) = doc else {
        return Err(JsonError::WrongShape { path: String::new(), expected: "an object".into(), found: describe(&doc) });
    };
    if let Some(found) = doc.get("type") {
        let found = found.as_str().map(str::to_owned).unwrap_or_else(|| found.to_string());
        if MessageType::from_name(&found) != Ok(kind) {
            return Err(JsonError::TypeMismatch { expected: kind.name(), found });
        }
    }
    let representation = match doc.get("representation") {
        None | Some(Value::Null) => None,
        Some(v) => Some(v.as_str().and_then(Representation::from_name).ok_or_else(|| JsonError::BadHeaderField {
            field: "representation",
            found: v.to_string(),
            allowed: "\"xcdr1\", \"xcdr2\"",
        })?),
    };
    let endianness = match doc.get("endianness") {
        None | Some(Value::Null) => None,
        Some(v) => Some(v.as_str().and_then(Endianness::from_name).ok_or_else(|| JsonError::BadHeaderField {
            field: "endianness",
            found: v.to_string(),
            allowed: "\"little\", \"big\"",
        })?),
    };
    let value = doc.get("value").ok_or(JsonError::MissingValue)?;
    Ok(Document { value: value_from_json(value)?, representation, endianness })
}

/// Builds a `T` from the JSON form of its value. Every member must be present, no unknown
/// member is accepted, and every number must fit its member's type exactly.
pub fn value_from_json<T: IdlStruct>(json: &Value) -> Result<T, JsonError> {
    let mut value = T::zeroed();
    let mut reader = JsonReader { path: Vec::new(), current: Vec::new() };
    reader.fill_object(json, &mut value)?;
    Ok(value)
}

fn describe(v: &Value) -> String {
    match v {
        Value::Null => "null".into(),
        Value::Bool(b) => format!("boolean {b}"),
        Value::Number(n) => format!("number {n}"),
        Value::String(s) => format!("string {s:?}"),
        Value::Array(a) => format!("an array of {} elements", a.len()),
        Value::Object(_) => "an object".into(),
    }
}

enum Segment {
    Member(&'static str),
    Index(usize),
}

struct JsonReader<'v> {
    path: Vec<Segment>,
    /// Objects being filled, innermost last.
    current: Vec<&'v Map<String, Value>>,
}

impl<'v> JsonReader<'v> {
    fn path_text(&self) -> String {
        let mut s = String::new();
        for seg in &self.path {
            match seg {
                Segment::Member(m) => {
                    if !s.is_empty() {
                        s.push('.');
                    }
                    s.push_str(m);
                }
                Segment::Index(i) => {
                    let _ = write!(s, "[{i}]");
                }
            }
        }
        if s.is_empty() {
            s.push_str("value");
        }
        s
    }

    fn shape(&self, expected: &str, found: &Value) -> JsonError {
        JsonError::WrongShape { path: self.path_text(), expected: expected.into(), found: describe(found) }
    }

    fn fill_object<S: IdlStruct>(&mut self, json: &'v Value, value: &mut S) -> Result<(), JsonError> {
        let Value::Object(map) = json else {
            return Err(self.shape("an object", json));
        };
        if let Some(unknown) = map.keys().find(|k| !S::MEMBERS.contains(&k.as_str())) {
            return Err(JsonError::UnknownMember { path: self.path_text(), member: unknown.clone() });
        }
        self.current.push(map);
        let result = value.walk_mut(self);
        self.current.pop();
        result
    }

    fn member(&self, name: &'static str) -> Result<&'v Value, JsonError> {
        let map = self.current.last().copied();
        map.and_then(|m| m.get(name)).ok_or_else(|| JsonError::MissingMember { path: self.path_text(), member: name })
    }

    fn array(&self, json: &'v Value, len: Option<usize>) -> Result<&'v Vec<Value>, JsonError> {
        let Value::Array(items) = json else {
            return Err(self.shape("an array", json));
        };
        match len {
            Some(n) if n != items.len() => {
                Err(JsonError::WrongLength { path: self.path_text(), expected: n, found: items.len() })
            }
            _ => Ok(items),
        }
    }

    fn parse_primitive<P: Primitive>(&self, json: &Value) -> Result<P, JsonError> {
        let out_of_range =
            |kind: &'static str| JsonError::OutOfRange { path: self.path_text(), value: json.to_string(), kind };
        match P::KIND {
            PrimKind::F32 => {
                let x = match json {
                    Value::Number(n) => n.to_string().parse::<f32>().map_err(|_| self.shape("a float", json))?,
                    Value::String(s) => parse_special_float(s)
                        .ok_or_else(|| self.shape("a number, \"NaN\", \"Infinity\" or \"-Infinity\"", json))?,
                    _ => return Err(self.shape("a number", json)),
                };
                Ok(P::from_bits(u64::from(x.to_bits())))
            }
            PrimKind::Bool => match json {
                Value::Bool(b) => Ok(P::from_bits(u64::from(*b))),
                _ => Err(self.shape("a boolean", json)),
            },
            kind => {
                let Value::Number(n) = json else {
                    return Err(self.shape("an integer", json));
                };
                let Some(i) = n.as_i64() else {
                    return Err(if n.as_u64().is_some() {
                        out_of_range(kind_name(kind))
                    } else {
                        self.shape("an integer", json)
                    });
                };
                let (lo, hi) = match kind {
                    PrimKind::U8 | PrimKind::Bool => (0, i64::from(u8::MAX)),
                    PrimKind::I16 => (i64::from(i16::MIN), i64::from(i16::MAX)),
                    PrimKind::U16 => (0, i64::from(u16::MAX)),
                    PrimKind::I32 => (i64::from(i32::MIN), i64::from(i32::MAX)),
                    PrimKind::U32 | PrimKind::F32 => (0, i64::from(u32::MAX)),
                    PrimKind::I64 => (i64::MIN, i64::MAX),
                };
                if i < lo || i > hi {
                    return Err(out_of_range(kind_name(kind)));
                }
                Ok(P::from_bits(i as u64))
            }
        }
    }

    fn fill_struct_list<S: IdlStruct>(&mut self, items: &'v [Value], out: &mut [S]) -> Result<(), JsonError> {
        for (i, (json, item)) in items.iter().zip(out.iter_mut()).enumerate() {
            self.path.push(Segment::Index(i));
            self.fill_object(json, item)?;
            self.path.pop();
        }
        Ok(())
    }
}

fn kind_name(kind: PrimKind) -> &'static str {
    match kind {
        PrimKind::Bool => "boolean",
        PrimKind::I64 => "i64 (long long)",
        PrimKind::U8 => "u8 (octet)",
        PrimKind::I16 => "i16 (short)",
        PrimKind::U16 => "u16 (unsigned short)",
        PrimKind::I32 => "i32 (long)",
        PrimKind::U32 => "u32 (unsigned long)",
        PrimKind::F32 => "f32 (float)",
    }
}

fn parse_special_float(s: &str) -> Option<f32> {
    match s {
        "NaN" => Some(f32::from_bits(CANONICAL_NAN)),
        "Infinity" => Some(f32::INFINITY),
        "-Infinity" => Some(f32::NEG_INFINITY),
        _ => {
            let hex = s.strip_prefix("NaN:0x")?;
            let bits = u32::from_str_radix(hex, 16).ok()?;
            let x = f32::from_bits(bits);
            x.is_nan().then_some(x)
        }
    }
}

impl VisitorMut for JsonReader<'_> {
    type Error = JsonError;

    fn primitive<P: Primitive>(&mut self, name: &'static str, value: &mut P) -> Result<(), JsonError> {
        let json = self.member(name)?;
        self.path.push(Segment::Member(name));
        *value = self.parse_primitive(json)?;
        self.path.pop();
        Ok(())
    }

    fn primitive_array<P: Primitive>(&mut self, name: &'static str, items: &mut [P]) -> Result<(), JsonError> {
        let json = self.member(name)?;
        self.path.push(Segment::Member(name));
        let list = self.array(json, Some(items.len()))?;
        for (i, (json, item)) in list.iter().zip(items.iter_mut()).enumerate() {
            self.path.push(Segment::Index(i));
            *item = self.parse_primitive(json)?;
            self.path.pop();
        }
        self.path.pop();
        Ok(())
    }

    fn structure<S: IdlStruct>(&mut self, name: &'static str, value: &mut S) -> Result<(), JsonError> {
        let json = self.member(name)?;
        self.path.push(Segment::Member(name));
        self.fill_object(json, value)?;
        self.path.pop();
        Ok(())
    }

    fn struct_array<S: IdlStruct>(&mut self, name: &'static str, items: &mut [S]) -> Result<(), JsonError> {
        let json = self.member(name)?;
        self.path.push(Segment::Member(name));
        let list = self.array(json, Some(items.len()))?;
        self.fill_struct_list(list, items)?;
        self.path.pop();
        Ok(())
    }

    fn struct_sequence<S: IdlStruct>(&mut self, name: &'static str, items: &mut Vec<S>) -> Result<(), JsonError> {
        let json = self.member(name)?;
        self.path.push(Segment::Member(name));
        let list = self.array(json, None)?;
        *items = (0..list.len()).map(|_| S::zeroed()).collect();
        self.fill_struct_list(list, items)?;
        self.path.pop();
        Ok(())
    }

    fn primitive_sequence<P: Primitive>(&mut self, name: &'static str, items: &mut Vec<P>) -> Result<(), JsonError> {
        let json = self.member(name)?;
        self.path.push(Segment::Member(name));
        let list = self.array(json, None)?;
        items.clear();
        for (i, json) in list.iter().enumerate() {
            self.path.push(Segment::Index(i));
            items.push(self.parse_primitive(json)?);
            self.path.pop();
        }
        self.path.pop();
        Ok(())
    }

    fn string(&mut self, name: &'static str, value: &mut String) -> Result<(), JsonError> {
        let json = self.member(name)?;
        self.path.push(Segment::Member(name));
        let Value::String(text) = json else {
            return Err(self.shape("a string", json));
        };
        value.clone_from(text);
        self.path.pop();
        Ok(())
    }
}
