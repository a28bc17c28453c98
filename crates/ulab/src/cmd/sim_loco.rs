//! `ulab sim`'s locomotion service over DDS: one request reader and one response writer per served variant
//! (`rt/api/loco/request|response` for the H1 API, `rt/api/sport/...` for the G1 API), in front of
//! `sim_bridge::loco::LocoService`, which holds the logic. See that module for what each call does. Beside them,
//! unless turned off, the motion switcher (`rt/api/motion_switcher/request|response`,
//! `sim_bridge::motion_switcher`), which releases and selects that same service.

use anyhow::{Context, Result};
use dds_transport::{Participant, RawReader, RawWriter, ReaderOptions, Reliability, TopicSpec, WriterQos};
use lowlevel_codec::{cdr, Encoding};
use policy_runtime::{PolicyController, PolicySpec};
use sim_bridge::loco::{LocoService, DEFAULT_POLICY_SPEC};
use sim_bridge::motion_switcher::MotionSwitcherService;
use sim_bridge::SimRobot;
use std::path::{Path, PathBuf};
use unitree_idl::api::{self, loco::LocoApi};
use unitree_idl::IdlStruct;

/// The `--loco-api` list.
#[derive(Debug, Clone)]
pub struct LocoApis(pub Vec<LocoApi>);

/// Parses `--loco-api`.
pub fn parse_api(s: &str) -> Result<LocoApis, String> {
    let mut out = Vec::new();
    for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        match part {
            "h1" => out.push(api::loco::H1),
            "g1" => out.push(api::loco::G1),
            "none" => {}
            other => return Err(format!("unknown locomotion API `{other}` (h1, g1, none)")),
        }
    }
    Ok(LocoApis(out))
}

/// The walking policy: the spec at `path`, or the shipped unitree_rl_gym H1-2 spec; `Err` says why none loads.
pub fn load_policy(path: Option<&Path>, model: &robot_model::RobotModel, dt: f64) -> Result<PolicyController, String> {
    let spec = match path {
        Some(p) => PolicySpec::load(p),
        None => PolicySpec::from_toml_str(DEFAULT_POLICY_SPEC, &PathBuf::from(".")),
    }
    .map_err(|e| e.to_string())?;
    spec.check_robot(model).map_err(|e| e.to_string())?;
    let period = spec.control_period;
    spec.decimation(dt).map_err(|e| format!("policy period {period} s with physics step {dt} s: {e}"))?;
    PolicyController::from_spec(spec).map_err(|e| e.to_string())
}

/// The services and their DDS endpoints.
#[derive(Debug)]
pub struct LocoEndpoints {
    service: LocoService,
    endpoints: Vec<(LocoApi, RawReader, RawWriter)>,
    /// The motion switcher, when served.
    switcher: Option<(MotionSwitcherService, RawReader, RawWriter)>,
    malformed: u64,
}

/// `rt/api/<service>/request` (reader, reliable) and `.../response` (writer).
fn rpc_endpoints(participant: &Participant, service: &str) -> Result<(RawReader, RawWriter)> {
    let request = TopicSpec::new(api::request_topic(service), api::Request_::DDS_TYPE_NAME);
    let response = TopicSpec::new(api::response_topic(service), api::Response_::DDS_TYPE_NAME);
    let opts = ReaderOptions { reliability: Reliability::Reliable, history_depth: 16, queue_capacity: 256 };
    let reader = participant.reader_with(&request, opts).with_context(|| format!("subscribing {}", request.name))?;
    let writer = participant
        .writer_with_qos(&response, WriterQos { reliability: Reliability::Reliable, history_depth: 16 })
        .with_context(|| format!("creating the {} writer", response.name))?;
    Ok((reader, writer))
}

/// The requests waiting on `reader`, decoded (malformed ones counted in `malformed` and reported).
fn pending(reader: &RawReader, malformed: &mut u64) -> Vec<api::Request_> {
    let mut out = Vec::new();
    while let Some(sample) = reader.try_take() {
        match cdr::decode::<api::Request_>(&sample.data) {
            Ok(d) => out.push(d.value),
            Err(e) => {
                *malformed += 1;
                eprintln!("sim: malformed request on {}: {e}", reader.topic().name);
            }
        }
    }
    out
}

fn answer(writer: &RawWriter, response: Option<api::Response_>) {
    if let Some(response) = response {
        if let Err(e) = writer.write(&cdr::encode(&response, Encoding::UNITREE)) {
            eprintln!("sim: answering on {} failed: {e}", writer.topic().name);
        }
    }
}

impl LocoEndpoints {
    /// Opens the request reader and response writer of every locomotion variant, and of the motion switcher
    /// (`rt/api/motion_switcher/...`) when `motion_switcher` is set.
    pub fn open(participant: &Participant, service: LocoService, motion_switcher: bool) -> Result<Self> {
        let mut endpoints = Vec::new();
        for api in service.apis().to_vec() {
            let (reader, writer) = rpc_endpoints(participant, api.service)?;
            endpoints.push((api, reader, writer));
        }
        let switcher = if motion_switcher {
            let (reader, writer) = rpc_endpoints(participant, api::motion_switcher::SERVICE)?;
            Some((MotionSwitcherService::new(), reader, writer))
        } else {
            None
        };
        Ok(LocoEndpoints { service, endpoints, switcher, malformed: 0 })
    }

    /// Answers every pending request.
    pub fn serve(&mut self, robot: &mut SimRobot, sim_time: f64, now: f64) {
        for (api, reader, writer) in &self.endpoints {
            for request in pending(reader, &mut self.malformed) {
                answer(writer, self.service.handle(api, &request, robot, sim_time, now));
            }
        }
        if let Some((switcher, reader, writer)) = self.switcher.as_mut() {
            for request in pending(reader, &mut self.malformed) {
                answer(writer, switcher.handle(&request, &mut self.service, robot, sim_time, now));
            }
        }
    }

    /// Runs the service's controller before a physics step.
    pub fn control(&mut self, robot: &mut SimRobot, sim_time: f64, now: f64) {
        self.service.control(robot, sim_time, now);
    }

    /// Events to print (state changes, takeovers, failures).
    pub fn take_events(&mut self) -> Vec<String> {
        self.service.take_events()
    }

    /// Short state for the status line.
    pub fn status(&self, sim_time: f64) -> String {
        let v = self.service.velocity(sim_time);
        let released = if self.service.released() { " (released)" } else { "" };
        format!("loco {:?}{released} v=({:.2}, {:.2}, {:.2})", self.service.mode(), v[0], v[1], v[2])
    }

    /// The account for the summary line.
    pub fn summary(&self) -> serde_json::Value {
        serde_json::json!({
            "services": self.endpoints.iter().map(|(a, _, _)| a.service).collect::<Vec<_>>(),
            "mode": self.service.mode(),
            "counters": self.service.counters(),
            "released": self.service.released(),
            "motion_switcher": self.switcher.as_ref().map(|(s, _, _)| serde_json::json!({
                "name": MotionSwitcherService::active_name(&self.service),
                "silent": s.silent(),
                "counters": s.counters(),
            })),
            "malformed_requests": self.malformed,
        })
    }
}
