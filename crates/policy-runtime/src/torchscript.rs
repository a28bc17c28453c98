//! Reading the float tensors of a TorchScript archive (`torch.jit.save`, e.g. legged_gym's exported
//! `policy_lstm_1.pt`) without PyTorch.
//!
//! The archive is a zip: `<root>/data.pkl` pickles the module tree (protocol 2), each tensor a
//! `torch._utils._rebuild_tensor_v2(persistent_id(('storage', torch.FloatStorage, key, device, numel)),
//! offset, shape, stride, …)`, and `<root>/data/<key>` holds each storage's raw bytes (`<root>/byteorder`,
//! little-endian here). We run the handful of pickle opcodes such files use, then walk the module tree and name
//! every tensor attribute by its path (`memory.weight_ih_l0`, `actor.0.bias`, …), as `state_dict()` would.
//! Only float32 storages are supported (what policies are exported in).

use crate::PolicyError;
use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

/// Named float arrays (`f64` values, shape) read from a model file.
pub type NamedArrays = std::collections::BTreeMap<String, (Vec<f64>, Vec<usize>)>;

fn err(path: &Path, reason: impl std::fmt::Display) -> PolicyError {
    PolicyError::Model { path: path.display().to_string(), reason: format!("TorchScript archive: {reason}") }
}

/// A pickled value, as far as module files need it.
#[derive(Debug, Clone)]
#[allow(dead_code)] // some payloads are only read through `Debug`, in error messages
enum Value {
    None,
    Bool(bool),
    Int(i64),
    Float(f64),
    Str(String),
    Tuple(Vec<Value>),
    List(Vec<Value>),
    Dict(Vec<(Value, Value)>),
    Global(String, String),
    /// An object built by NEWOBJ / REDUCE of an unknown callable, with its BUILD state.
    Object {
        class: String,
        state: Box<Value>,
    },
    /// `persistent_id(...)` (a storage reference).
    PersId(Box<Value>),
    Tensor(TensorRef),
    Mark,
}

#[derive(Debug, Clone)]
struct TensorRef {
    storage_key: String,
    storage_type: String,
    offset: usize,
    shape: Vec<usize>,
    stride: Vec<usize>,
}

const MAX_OPS: usize = 10_000_000;

struct Machine<'a> {
    data: &'a [u8],
    pos: usize,
    stack: Vec<Value>,
    memo: HashMap<u32, Value>,
}

impl<'a> Machine<'a> {
    fn byte(&mut self) -> Result<u8, String> {
        let b = *self.data.get(self.pos).ok_or("truncated pickle")?;
        self.pos += 1;
        Ok(b)
    }

    fn bytes(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self.pos.checked_add(n).ok_or("length overflow")?;
        let s = self.data.get(self.pos..end).ok_or("truncated pickle")?;
        self.pos = end;
        Ok(s)
    }

    fn u32le(&mut self) -> Result<u32, String> {
        let b = self.bytes(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn line(&mut self) -> Result<String, String> {
        let rest = self.data.get(self.pos..).ok_or("truncated pickle")?;
        let n = rest.iter().position(|&b| b == b'\n').ok_or("unterminated text argument")?;
        let s = std::str::from_utf8(&rest[..n]).map_err(|e| e.to_string())?.to_string();
        self.pos += n + 1;
        Ok(s)
    }

    fn pop(&mut self) -> Result<Value, String> {
        self.stack.pop().ok_or_else(|| "pickle stack underflow".to_string())
    }

    fn pop_mark(&mut self) -> Result<Vec<Value>, String> {
        let at = self.stack.iter().rposition(|v| matches!(v, Value::Mark)).ok_or("MARK not found")?;
        let items = self.stack.split_off(at + 1);
        self.stack.pop();
        Ok(items)
    }

    fn top(&mut self) -> Result<&mut Value, String> {
        self.stack.last_mut().ok_or_else(|| "pickle stack underflow".to_string())
    }

    fn run(mut self) -> Result<Value, String> {
        for _ in 0..MAX_OPS {
            let op = self.byte()?;
            match op {
                0x80 => {
                    self.byte()?; // PROTO
                }
                b'.' => return self.pop(), // STOP
                b'(' => self.stack.push(Value::Mark),
                b')' => self.stack.push(Value::Tuple(Vec::new())),
                b']' => self.stack.push(Value::List(Vec::new())),
                b'}' => self.stack.push(Value::Dict(Vec::new())),
                b'N' => self.stack.push(Value::None),
                0x88 => self.stack.push(Value::Bool(true)),
                0x89 => self.stack.push(Value::Bool(false)),
                b'K' => {
                    let v = self.byte()?;
                    self.stack.push(Value::Int(i64::from(v)));
                }
                b'M' => {
                    let b = self.bytes(2)?;
                    self.stack.push(Value::Int(i64::from(u16::from_le_bytes([b[0], b[1]]))));
                }
                b'J' => {
                    let v = self.u32le()? as i32;
                    self.stack.push(Value::Int(i64::from(v)));
                }
                0x8a => {
                    // LONG1: little-endian two's complement of n bytes
                    let n = usize::from(self.byte()?);
                    let b = self.bytes(n)?;
                    if n > 8 {
                        return Err("LONG1 wider than 64 bits".into());
                    }
                    let mut v: i64 = 0;
                    for (i, &x) in b.iter().enumerate() {
                        v |= i64::from(x) << (8 * i);
                    }
                    if n > 0 && n < 8 && b[n - 1] & 0x80 != 0 {
                        v -= 1i64 << (8 * n);
                    }
                    self.stack.push(Value::Int(v));
                }
                b'G' => {
                    let b = self.bytes(8)?;
                    let mut a = [0u8; 8];
                    a.copy_from_slice(b);
                    self.stack.push(Value::Float(f64::from_be_bytes(a)));
                }
                b'X' => {
                    let n = self.u32le()? as usize;
                    let s = std::str::from_utf8(self.bytes(n)?).map_err(|e| e.to_string())?.to_string();
                    self.stack.push(Value::Str(s));
                }
                0x8c => {
                    // SHORT_BINUNICODE
                    let n = usize::from(self.byte()?);
                    let s = std::str::from_utf8(self.bytes(n)?).map_err(|e| e.to_string())?.to_string();
                    self.stack.push(Value::Str(s));
                }
                b'c' => {
                    let module = self.line()?;
                    let name = self.line()?;
                    self.stack.push(Value::Global(module, name));
                }
                b'q' => {
                    let k = u32::from(self.byte()?);
                    let v = self.top()?.clone();
                    self.memo.insert(k, v);
                }
                b'r' => {
                    let k = self.u32le()?;
                    let v = self.top()?.clone();
                    self.memo.insert(k, v);
                }
                b'h' => {
                    let k = u32::from(self.byte()?);
                    let v = self.memo.get(&k).cloned().ok_or("BINGET of an unknown memo key")?;
                    self.stack.push(v);
                }
                b'j' => {
                    let k = self.u32le()?;
                    let v = self.memo.get(&k).cloned().ok_or("LONG_BINGET of an unknown memo key")?;
                    self.stack.push(v);
                }
                b't' => {
                    let items = self.pop_mark()?;
                    self.stack.push(Value::Tuple(items));
                }
                0x85..=0x87 => {
                    let n = usize::from(op - 0x84);
                    if self.stack.len() < n {
                        return Err("pickle stack underflow".into());
                    }
                    let items = self.stack.split_off(self.stack.len() - n);
                    self.stack.push(Value::Tuple(items));
                }
                b'e' => {
                    let items = self.pop_mark()?;
                    match self.top()? {
                        Value::List(l) => l.extend(items),
                        _ => return Err("APPENDS to a non-list".into()),
                    }
                }
                b'a' => {
                    let item = self.pop()?;
                    match self.top()? {
                        Value::List(l) => l.push(item),
                        _ => return Err("APPEND to a non-list".into()),
                    }
                }
                b'u' => {
                    let items = self.pop_mark()?;
                    if items.len() % 2 != 0 {
                        return Err("SETITEMS with an odd item count".into());
                    }
                    let mut it = items.into_iter();
                    let mut pairs = Vec::new();
                    while let (Some(k), Some(v)) = (it.next(), it.next()) {
                        pairs.push((k, v));
                    }
                    match self.top()? {
                        Value::Dict(d) => d.extend(pairs),
                        _ => return Err("SETITEMS on a non-dict".into()),
                    }
                }
                b's' => {
                    let v = self.pop()?;
                    let k = self.pop()?;
                    match self.top()? {
                        Value::Dict(d) => d.push((k, v)),
                        _ => return Err("SETITEM on a non-dict".into()),
                    }
                }
                0x81 => {
                    // NEWOBJ: cls, args
                    let _args = self.pop()?;
                    let cls = self.pop()?;
                    let class = match cls {
                        Value::Global(m, n) => format!("{m}.{n}"),
                        _ => return Err("NEWOBJ of a non-class".into()),
                    };
                    self.stack.push(Value::Object { class, state: Box::new(Value::None) });
                }
                b'b' => {
                    // BUILD
                    let state = self.pop()?;
                    match self.top()? {
                        Value::Object { state: s, .. } => **s = state,
                        _ => return Err("BUILD on a non-object".into()),
                    }
                }
                b'Q' => {
                    let pid = self.pop()?;
                    self.stack.push(Value::PersId(Box::new(pid)));
                }
                b'R' => {
                    let args = self.pop()?;
                    let callable = self.pop()?;
                    let v = reduce(callable, args)?;
                    self.stack.push(v);
                }
                other => return Err(format!("unsupported pickle opcode 0x{other:02x} at byte {}", self.pos - 1)),
            }
        }
        Err("pickle too long".into())
    }
}

fn as_usize(v: &Value) -> Result<usize, String> {
    match v {
        Value::Int(i) if *i >= 0 => Ok(*i as usize),
        other => Err(format!("expected a non-negative integer, got {other:?}")),
    }
}

fn usize_tuple(v: &Value) -> Result<Vec<usize>, String> {
    match v {
        Value::Tuple(items) => items.iter().map(as_usize).collect(),
        other => Err(format!("expected a tuple of integers, got {other:?}")),
    }
}

/// REDUCE: tensors from `_rebuild_tensor_v2`, `OrderedDict()` as a dict, TorchScript's type-tag helpers as
/// their argument, anything else as an opaque object.
fn reduce(callable: Value, args: Value) -> Result<Value, String> {
    let Value::Global(module, name) = callable else {
        return Err("REDUCE of a non-global callable".into());
    };
    let Value::Tuple(args) = args else {
        return Err("REDUCE with non-tuple arguments".into());
    };
    match (module.as_str(), name.as_str()) {
        ("torch._utils", "_rebuild_tensor_v2") => {
            if args.len() < 4 {
                return Err("_rebuild_tensor_v2 with too few arguments".into());
            }
            let Value::PersId(pid) = &args[0] else {
                return Err("tensor storage is not a persistent id".into());
            };
            let Value::Tuple(p) = pid.as_ref() else {
                return Err("storage persistent id is not a tuple".into());
            };
            let (storage_type, storage_key) = match p.as_slice() {
                [Value::Str(tag), Value::Global(_, ty), Value::Str(key), ..] if tag == "storage" => {
                    (ty.clone(), key.clone())
                }
                _ => return Err(format!("unexpected storage id {p:?}")),
            };
            Ok(Value::Tensor(TensorRef {
                storage_key,
                storage_type,
                offset: as_usize(&args[1])?,
                shape: usize_tuple(&args[2])?,
                stride: usize_tuple(&args[3])?,
            }))
        }
        ("collections", "OrderedDict") => Ok(Value::Dict(Vec::new())),
        ("torch.jit._pickle", "restore_type_tag") | ("torch.jit._pickle", "build_tensorlist") => {
            Ok(args.into_iter().next().unwrap_or(Value::None))
        }
        _ => Ok(Value::Object { class: format!("{module}.{name}"), state: Box::new(Value::Tuple(args)) }),
    }
}

/// Tensor attributes of the module tree, by dotted path (module attributes only, like `state_dict()`).
fn collect(value: &Value, prefix: &str, out: &mut Vec<(String, TensorRef)>) {
    let Value::Object { state, .. } = value else {
        return;
    };
    let Value::Dict(items) = state.as_ref() else {
        return;
    };
    for (k, v) in items {
        let Value::Str(key) = k else { continue };
        let name = if prefix.is_empty() { key.clone() } else { format!("{prefix}.{key}") };
        match v {
            Value::Tensor(t) => out.push((name, t.clone())),
            Value::Object { .. } => collect(v, &name, out),
            _ => {}
        }
    }
}

/// Every float tensor attribute of the archive's module tree, by `state_dict()`-style name.
pub fn read_tensors(path: &Path) -> Result<NamedArrays, PolicyError> {
    if !path.is_file() {
        return Err(crate::SpecError::MissingFile { path: path.display().to_string() }.into());
    }
    let file = std::fs::File::open(path).map_err(|e| err(path, e))?;
    let mut zip = zip::ZipArchive::new(file).map_err(|e| err(path, e))?;
    let pkl_name = zip
        .file_names()
        .map(str::to_string)
        .find(|n| n.ends_with("/data.pkl") && n.matches('/').count() == 1)
        .ok_or_else(|| err(path, "no <root>/data.pkl"))?;
    let root = pkl_name.trim_end_matches("data.pkl").to_string();
    let read = |zip: &mut zip::ZipArchive<std::fs::File>, name: &str| -> Result<Vec<u8>, PolicyError> {
        let mut f = zip.by_name(name).map_err(|e| err(path, format!("{name}: {e}")))?;
        let mut buf = Vec::new();
        f.read_to_end(&mut buf).map_err(|e| err(path, format!("{name}: {e}")))?;
        Ok(buf)
    };
    if let Ok(order) = read(&mut zip, &format!("{root}byteorder")) {
        if order.trim_ascii() != b"little" {
            return Err(err(path, "big-endian storages are not supported"));
        }
    }
    let pkl = read(&mut zip, &pkl_name)?;
    let module =
        Machine { data: &pkl, pos: 0, stack: Vec::new(), memo: HashMap::new() }.run().map_err(|e| err(path, e))?;
    let mut tensors = Vec::new();
    collect(&module, "", &mut tensors);
    if tensors.is_empty() {
        return Err(err(path, "no tensors in the module"));
    }
    let mut out = NamedArrays::new();
    for (name, t) in tensors {
        if t.storage_type != "FloatStorage" {
            return Err(err(path, format!("{name}: {} (only float32 is supported)", t.storage_type)));
        }
        let bytes = read(&mut zip, &format!("{root}data/{}", t.storage_key))?;
        let storage: Vec<f32> = bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
        if t.shape.len() != t.stride.len() {
            return Err(err(path, format!("{name}: shape {:?} and stride {:?} differ in rank", t.shape, t.stride)));
        }
        // Gather in row-major order through the strides.
        // Saved parameters are dense views: never more elements than their storage holds.
        let n = t
            .shape
            .iter()
            .try_fold(1usize, |acc, &d| acc.checked_mul(d))
            .filter(|&n| n <= storage.len())
            .ok_or_else(|| err(path, format!("{name}: shape {:?} exceeds its storage", t.shape)))?;
        let mut data = Vec::with_capacity(n);
        let mut idx = vec![0usize; t.shape.len()];
        for _ in 0..n {
            let at = t.offset + idx.iter().zip(&t.stride).map(|(i, s)| i * s).sum::<usize>();
            let v = storage.get(at).ok_or_else(|| err(path, format!("{name}: index {at} outside its storage")))?;
            data.push(f64::from(*v));
            for d in (0..idx.len()).rev() {
                idx[d] += 1;
                if idx[d] < t.shape[d] {
                    break;
                }
                idx[d] = 0;
            }
        }
        out.insert(name, (data, t.shape));
    }
    Ok(out)
}
