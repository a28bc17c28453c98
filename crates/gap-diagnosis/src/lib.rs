//! `gap-diagnosis`: Sim-to-real gap diagnosis: residual breakdown, effect library, held-out ranking, blind benchmark (issue 6).
#![forbid(unsafe_code)]
