//! `policy-runtime`: RL policies for the H1-2 (ONNX via tract, unitree_rl_gym LSTM from arrays) behind one controller interface (issue 5).
#![forbid(unsafe_code)]
