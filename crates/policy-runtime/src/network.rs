//! The networks themselves: an ONNX feed-forward policy run with tract, and rsl_rl's recurrent actor (one LSTM
//! layer, then an ELU MLP) evaluated from its weight arrays. Both take and return `f32`, the precision they were
//! trained and exported in.

use crate::spec::LstmInitialState;
use crate::PolicyError;
use std::path::Path;

fn model_err(path: &Path, reason: impl std::fmt::Display) -> PolicyError {
    PolicyError::Model { path: path.display().to_string(), reason: reason.to_string() }
}

#[cfg(not(feature = "onnx"))]
pub use no_onnx::OnnxPolicy;
#[cfg(feature = "onnx")]
pub use onnx::OnnxPolicy;

/// ONNX inference with tract (feature `onnx`, on by default; the fuzz build leaves it out because the engine
/// fuzz target never runs a policy and instrumenting tract doubles its build time).
#[cfg(feature = "onnx")]
mod onnx {
    use super::model_err;
    use crate::PolicyError;
    use std::path::{Path, PathBuf};
    use std::sync::Arc;
    use tract_onnx::prelude::*;

    /// A feed-forward ONNX policy with one input `[1, n]` and one output `[1, m]` (rsl_rl's ONNX export).
    #[derive(Debug, Clone)]
    pub struct OnnxPolicy {
        path: PathBuf,
        plan: Arc<TypedRunnableModel>,
        input_dim: usize,
        output_dim: usize,
    }

    impl OnnxPolicy {
        /// Loads, type-checks and optimizes the model for a batch of one.
        pub fn load(path: &Path) -> Result<Self, PolicyError> {
            if !path.is_file() {
                return Err(crate::SpecError::MissingFile { path: path.display().to_string() }.into());
            }
            let model = tract_onnx::onnx().model_for_path(path).map_err(|e| model_err(path, format!("{e:#}")))?;
            let typed = model.into_typed().map_err(|e| model_err(path, format!("{e:#}")))?;
            if typed.inputs.len() != 1 || typed.outputs.len() != 1 {
                return Err(model_err(
                    path,
                    format!(
                        "expected one input and one output, found {} and {}",
                        typed.inputs.len(),
                        typed.outputs.len()
                    ),
                ));
            }
            let input_dim = flat_dim(&typed, typed.inputs[0], path, "input")?;
            let output_dim = flat_dim(&typed, typed.outputs[0], path, "output")?;
            let plan = typed
                .into_optimized()
                .and_then(|m| m.into_runnable())
                .map_err(|e| model_err(path, format!("{e:#}")))?;
            Ok(OnnxPolicy { path: path.to_path_buf(), plan, input_dim, output_dim })
        }

        pub fn input_dim(&self) -> usize {
            self.input_dim
        }

        pub fn output_dim(&self) -> usize {
            self.output_dim
        }

        /// One forward pass on one observation vector.
        pub fn forward(&self, obs: &[f32]) -> Result<Vec<f32>, PolicyError> {
            if obs.len() != self.input_dim {
                return Err(PolicyError::Inference(format!(
                    "{}: observation has {} values, the network takes {}",
                    self.path.display(),
                    obs.len(),
                    self.input_dim
                )));
            }
            let input =
                Tensor::from_shape(&[1, self.input_dim], obs).map_err(|e| PolicyError::Inference(format!("{e:#}")))?;
            let out =
                self.plan.run(tvec!(input.into_tvalue())).map_err(|e| PolicyError::Inference(format!("{e:#}")))?;
            let first = out.first().ok_or_else(|| PolicyError::Inference("network returned no output".into()))?;
            let view = first.to_plain_array_view::<f32>().map_err(|e| PolicyError::Inference(format!("{e:#}")))?;
            let v: Vec<f32> = view.iter().copied().collect();
            if v.len() != self.output_dim {
                return Err(PolicyError::Inference(format!(
                    "network returned {} values, expected {}",
                    v.len(),
                    self.output_dim
                )));
            }
            Ok(v)
        }
    }

    /// Number of values in a `[1, n]` (or `[n]`) fact with concrete dimensions.
    fn flat_dim(model: &TypedModel, outlet: OutletId, path: &Path, what: &str) -> Result<usize, PolicyError> {
        let fact = model.outlet_fact(outlet).map_err(|e| model_err(path, format!("{e:#}")))?;
        let dims = fact
            .shape
            .as_concrete()
            .ok_or_else(|| model_err(path, format!("{what} shape {:?} is not concrete", fact.shape)))?;
        match dims {
            [n] | [1, n] => Ok(*n),
            other => Err(model_err(path, format!("{what} shape {other:?}: expected [1, n]"))),
        }
    }
}

/// Stand-in for builds without the `onnx` feature: loading fails with a clear error, so no value exists.
#[cfg(not(feature = "onnx"))]
mod no_onnx {
    use super::model_err;
    use crate::PolicyError;
    use std::path::Path;

    /// Uninhabited: `load` always fails in this build.
    #[derive(Debug, Clone)]
    pub struct OnnxPolicy {
        never: std::convert::Infallible,
    }

    impl OnnxPolicy {
        pub fn load(path: &Path) -> Result<Self, PolicyError> {
            Err(model_err(path, "this build has no ONNX runtime (policy-runtime without its `onnx` feature)"))
        }
        pub fn input_dim(&self) -> usize {
            match self.never {}
        }
        pub fn output_dim(&self) -> usize {
            match self.never {}
        }
        pub fn forward(&self, _obs: &[f32]) -> Result<Vec<f32>, PolicyError> {
            match self.never {}
        }
    }
}

/// A dense layer `y = W x + b` (`W` row-major, `out × in`).
#[derive(Debug, Clone)]
struct Linear {
    w: Vec<f64>,
    b: Vec<f64>,
    n_in: usize,
    n_out: usize,
}

impl Linear {
    fn apply(&self, x: &[f64], y: &mut Vec<f64>) {
        y.clear();
        for o in 0..self.n_out {
            let row = &self.w[o * self.n_in..(o + 1) * self.n_in];
            y.push(self.b[o] + row.iter().zip(x).map(|(w, x)| w * x).sum::<f64>());
        }
    }
}

fn elu(x: f64) -> f64 {
    if x > 0.0 {
        x
    } else {
        x.exp_m1()
    }
}

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

/// rsl_rl's recurrent actor: `h, c = LSTM(obs, h, c)`, action = MLP(h) (ELU between linear layers, none after
/// the last). PyTorch's LSTM: gates `W_ih x + b_ih + W_hh h + b_hh` split in order input, forget, cell, output.
/// The recurrent state persists between calls until [`LstmPolicy::reset`]. Computed in `f64` from the `f32`
/// weights.
#[derive(Debug, Clone)]
pub struct LstmPolicy {
    n_in: usize,
    n_hidden: usize,
    /// `4H × I`, row-major.
    w_ih: Vec<f64>,
    /// `4H × H`, row-major.
    w_hh: Vec<f64>,
    /// `b_ih + b_hh` (4H).
    bias: Vec<f64>,
    actor: Vec<Linear>,
    h0: Vec<f64>,
    c0: Vec<f64>,
    h: Vec<f64>,
    c: Vec<f64>,
}

pub use crate::torchscript::NamedArrays;

/// Every array of an `.npz` archive (all must be `float32`).
pub fn read_npz(path: &Path) -> Result<NamedArrays, PolicyError> {
    if !path.is_file() {
        return Err(crate::SpecError::MissingFile { path: path.display().to_string() }.into());
    }
    let mut npz = npyz::npz::NpzArchive::open(path).map_err(|e| model_err(path, e))?;
    let names: Vec<String> = npz.array_names().map(str::to_string).collect();
    let mut out = NamedArrays::new();
    for name in names {
        let npy = npz
            .by_name(&name)
            .map_err(|e| model_err(path, format!("array `{name}`: {e}")))?
            .ok_or_else(|| model_err(path, format!("array `{name}` missing")))?;
        let shape: Vec<usize> = npy.shape().iter().map(|&d| d as usize).collect();
        let data: Vec<f32> =
            npy.into_vec().map_err(|e| model_err(path, format!("array `{name}`: {e} (expected float32)")))?;
        out.insert(name, (data.into_iter().map(f64::from).collect(), shape));
    }
    Ok(out)
}

fn take(arrays: &NamedArrays, name: &str, path: &Path) -> Result<(Vec<f64>, Vec<usize>), PolicyError> {
    arrays.get(name).cloned().ok_or_else(|| model_err(path, format!("array `{name}` missing")))
}

impl LstmPolicy {
    /// From an `.npz` archive; see [`LstmPolicy::from_arrays`] for the arrays it needs.
    pub fn load(path: &Path, initial: LstmInitialState) -> Result<Self, PolicyError> {
        Self::from_arrays(&read_npz(path)?, initial, path)
    }

    /// From the TorchScript archive (`.pt`) that rsl_rl's / legged_gym's `PolicyExporterLSTM` writes, read
    /// directly (zip + pickle; no PyTorch); the same arrays as the `.npz` export.
    pub fn load_torchscript(path: &Path, initial: LstmInitialState) -> Result<Self, PolicyError> {
        Self::from_arrays(&crate::torchscript::read_tensors(path)?, initial, path)
    }

    /// Uses `memory.{weight,bias}_{ih,hh}_l0`, `actor.<k>.{weight,bias}` and, for
    /// [`LstmInitialState::Stored`], `hidden_state` / `cell_state` (shape `[1, 1, H]`). `path` names the
    /// source in errors.
    pub fn from_arrays(arrays: &NamedArrays, initial: LstmInitialState, path: &Path) -> Result<Self, PolicyError> {
        let names: Vec<&String> = arrays.keys().collect();
        let (w_ih, s_ih) = take(arrays, "memory.weight_ih_l0", path)?;
        let (w_hh, s_hh) = take(arrays, "memory.weight_hh_l0", path)?;
        let (b_ih, s_bih) = take(arrays, "memory.bias_ih_l0", path)?;
        let (b_hh, s_bhh) = take(arrays, "memory.bias_hh_l0", path)?;
        let (n4, n_in) = match s_ih[..] {
            [a, b] => (a, b),
            _ => return Err(model_err(path, format!("memory.weight_ih_l0 shape {s_ih:?}"))),
        };
        if n4 == 0 || n4 % 4 != 0 {
            return Err(model_err(path, format!("memory.weight_ih_l0 has {n4} rows, not 4·hidden")));
        }
        let n_hidden = n4 / 4;
        if s_hh != [n4, n_hidden] || s_bih != [n4] || s_bhh != [n4] {
            return Err(model_err(
                path,
                format!("LSTM shapes disagree: W_hh {s_hh:?}, b_ih {s_bih:?}, b_hh {s_bhh:?}"),
            ));
        }
        if names.iter().any(|n| n.starts_with("memory.") && n.ends_with("_l1")) {
            return Err(model_err(path, "multi-layer LSTM not supported (found *_l1 arrays)"));
        }
        let bias: Vec<f64> = b_ih.iter().zip(&b_hh).map(|(a, b)| a + b).collect();

        // Actor layers, by index (actor.0, actor.2, ...: activations sit at the odd indices).
        let mut idx: Vec<usize> =
            names.iter().filter_map(|n| n.strip_prefix("actor.")?.strip_suffix(".weight")?.parse().ok()).collect();
        idx.sort_unstable();
        if idx.is_empty() {
            return Err(model_err(path, "no actor.<k>.weight arrays"));
        }
        let mut actor = Vec::with_capacity(idx.len());
        let mut width = n_hidden;
        for k in idx {
            let (w, sw) = take(arrays, &format!("actor.{k}.weight"), path)?;
            let (b, sb) = take(arrays, &format!("actor.{k}.bias"), path)?;
            let (n_out, n_in_k) = match sw[..] {
                [a, b] => (a, b),
                _ => return Err(model_err(path, format!("actor.{k}.weight shape {sw:?}"))),
            };
            if n_in_k != width || sb != [n_out] {
                return Err(model_err(
                    path,
                    format!("actor.{k}: weight {sw:?}, bias {sb:?} do not follow a layer of width {width}"),
                ));
            }
            actor.push(Linear { w, b, n_in: n_in_k, n_out });
            width = n_out;
        }

        let (h0, c0) = match initial {
            LstmInitialState::Zeros => (vec![0.0; n_hidden], vec![0.0; n_hidden]),
            LstmInitialState::Stored => {
                let (h, sh) = take(arrays, "hidden_state", path)?;
                let (c, sc) = take(arrays, "cell_state", path)?;
                if h.len() != n_hidden || c.len() != n_hidden {
                    return Err(model_err(path, format!("stored state shapes {sh:?}, {sc:?}; hidden size {n_hidden}")));
                }
                (h, c)
            }
        };
        Ok(LstmPolicy { n_in, n_hidden, w_ih, w_hh, bias, actor, h: h0.clone(), c: c0.clone(), h0, c0 })
    }

    pub fn input_dim(&self) -> usize {
        self.n_in
    }

    pub fn output_dim(&self) -> usize {
        self.actor.last().map_or(self.n_hidden, |l| l.n_out)
    }

    /// Back to the initial recurrent state.
    pub fn reset(&mut self) {
        self.h.clone_from(&self.h0);
        self.c.clone_from(&self.c0);
    }

    /// Current hidden state `h` (H values).
    pub fn hidden_state(&self) -> &[f64] {
        &self.h
    }

    /// Current cell state `c` (H values).
    pub fn cell_state(&self) -> &[f64] {
        &self.c
    }

    /// One step: advances the recurrent state and returns the action.
    pub fn step(&mut self, obs: &[f32]) -> Result<Vec<f32>, PolicyError> {
        if obs.len() != self.n_in {
            return Err(PolicyError::Inference(format!(
                "observation has {} values, the LSTM takes {}",
                obs.len(),
                self.n_in
            )));
        }
        let (n_h, n_i) = (self.n_hidden, self.n_in);
        let x: Vec<f64> = obs.iter().map(|&v| f64::from(v)).collect();
        let mut gates = self.bias.clone();
        for (r, g) in gates.iter_mut().enumerate() {
            let wi = &self.w_ih[r * n_i..(r + 1) * n_i];
            let wh = &self.w_hh[r * n_h..(r + 1) * n_h];
            *g += wi.iter().zip(&x).map(|(w, v)| w * v).sum::<f64>()
                + wh.iter().zip(&self.h).map(|(w, v)| w * v).sum::<f64>();
        }
        for k in 0..n_h {
            let i = sigmoid(gates[k]);
            let f = sigmoid(gates[n_h + k]);
            let g = gates[2 * n_h + k].tanh();
            let o = sigmoid(gates[3 * n_h + k]);
            self.c[k] = f * self.c[k] + i * g;
            self.h[k] = o * self.c[k].tanh();
        }
        let mut a = self.h.clone();
        let mut b = Vec::new();
        let last = self.actor.len() - 1;
        for (l, layer) in self.actor.iter().enumerate() {
            layer.apply(&a, &mut b);
            if l != last {
                b.iter_mut().for_each(|v| *v = elu(*v));
            }
            std::mem::swap(&mut a, &mut b);
        }
        Ok(a.into_iter().map(|v| v as f32).collect())
    }
}

/// Either network behind one interface.
// One per controller, so the variants' size difference (an empty ONNX stand-in without the `onnx` feature) is moot.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
pub enum PolicyNetwork {
    Onnx(OnnxPolicy),
    Lstm(LstmPolicy),
}

impl PolicyNetwork {
    pub fn input_dim(&self) -> usize {
        match self {
            PolicyNetwork::Onnx(n) => n.input_dim(),
            PolicyNetwork::Lstm(n) => n.input_dim(),
        }
    }

    pub fn output_dim(&self) -> usize {
        match self {
            PolicyNetwork::Onnx(n) => n.output_dim(),
            PolicyNetwork::Lstm(n) => n.output_dim(),
        }
    }

    /// Clears recurrent state (no-op for feed-forward networks).
    pub fn reset(&mut self) {
        if let PolicyNetwork::Lstm(n) = self {
            n.reset();
        }
    }

    /// One policy call.
    pub fn step(&mut self, obs: &[f32]) -> Result<Vec<f32>, PolicyError> {
        match self {
            PolicyNetwork::Onnx(n) => n.forward(obs),
            PolicyNetwork::Lstm(n) => n.step(obs),
        }
    }
}
