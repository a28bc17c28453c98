//! `ulab sim`'s locomotion service over DDS: one request reader and one response writer per served variant
//! (`rt/api/loco/request|response` for the H1 API, `rt/api/sport/...` for the G1 API), in front of
//! `sim_bridge::loco::LocoService`, which holds the logic. See that module for what each call does.

use anyhow::{Context, Result};
use dds_transport::{Participant, RawReader, RawWriter, ReaderOptions, Reliability, TopicSpec, WriterQos};
use lowlevel_codec::{cdr, Encoding};
use policy_runtime::{PolicyController, PolicySpec};
use sim_bridge::loco::{LocoService, DEFAULT_POLICY_SPEC};
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

/// The service and its DDS endpoints.
#[derive(Debug)]
pub struct LocoEndpoints {
    service: LocoService,
    endpoints: Vec<(LocoApi, RawReader, RawWriter)>,
    malformed: u64,
}

impl LocoEndpoints {
    /// Opens `rt/api/<service>/request` (reader, reliable) and `.../response` (writer) for every variant.
    pub fn open(participant: &Participant, service: LocoService) -> Result<Self> {
        let mut endpoints = Vec::new();
        for api in service.apis().to_vec() {
            let request = TopicSpec::new(api::request_topic(api.service), api::Request_::DDS_TYPE_NAME);
            let response = TopicSpec::new(api::response_topic(api.service), api::Response_::DDS_TYPE_NAME);
            let opts = ReaderOptions { reliability: Reliability::Reliable, history_depth: 16, queue_capacity: 256 };
            let reader =
                participant.reader_with(&request, opts).with_context(|| format!("subscribing {}", request.name))?;
            let writer = participant
                .writer_with_qos(&response, WriterQos { reliability: Reliability::Reliable, history_depth: 16 })
                .with_context(|| format!("creating the {} writer", response.name))?;
            endpoints.push((api, reader, writer));
        }
        Ok(LocoEndpoints { service, endpoints, malformed: 0 })
    }

    /// Answers every pending request.
    pub fn serve(&mut self, robot: &mut SimRobot, sim_time: f64, now: f64) {
        for (api, reader, writer) in &self.endpoints {
            while let Some(sample) = reader.try_take() {
                let request = match cdr::decode::<api::Request_>(&sample.data) {
                    Ok(d) => d.value,
                    Err(e) => {
                        self.malformed += 1;
                        eprintln!("sim: malformed request on {}: {e}", reader.topic().name);
                        continue;
                    }
                };
                if let Some(response) = self.service.handle(api, &request, robot, sim_time, now) {
                    if let Err(e) = writer.write(&cdr::encode(&response, Encoding::UNITREE)) {
                        eprintln!("sim: answering on {} failed: {e}", writer.topic().name);
                    }
                }
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
        format!("loco {:?} v=({:.2}, {:.2}, {:.2})", self.service.mode(), v[0], v[1], v[2])
    }

    /// The account for the summary line.
    pub fn summary(&self) -> serde_json::Value {
        serde_json::json!({
            "services": self.endpoints.iter().map(|(a, _, _)| a.service).collect::<Vec<_>>(),
            "mode": self.service.mode(),
            "counters": self.service.counters(),
            "malformed_requests": self.malformed,
        })
    }
}
