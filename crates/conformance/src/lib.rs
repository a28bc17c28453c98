//! `conformance`: Conformance checks and fuzzing of a Unitree DDS peer that plays the robot side (issue 4).
#![forbid(unsafe_code)]
