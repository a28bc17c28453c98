//! Type names and QoS the peer announces in discovery, against Unitree's SDK.

use crate::report::{CheckId, CheckResult, Status};
use crate::target::Target;
use crate::ConformError;
use dds_transport::{Durability, EndpointKind, Reliability};

pub(super) fn types_qos(target: &Target) -> Result<CheckResult, ConformError> {
    let eps = target.remote_endpoints()?;
    let writers: Vec<_> = eps
        .iter()
        .filter(|e| e.kind == EndpointKind::Publication && e.topic_name == unitree_idl::topics::LOWSTATE)
        .collect();
    let readers: Vec<_> = eps
        .iter()
        .filter(|e| e.kind == EndpointKind::Subscription && e.topic_name == unitree_idl::topics::LOWCMD)
        .collect();
    let mut problems = Vec::new();
    for w in &writers {
        if w.type_name != dds_transport::topics::HG_LOWSTATE_TYPE {
            problems.push(format!(
                "rt/lowstate writer type `{}` (Unitree: `{}`)",
                w.type_name,
                dds_transport::topics::HG_LOWSTATE_TYPE
            ));
        }
    }
    if readers.is_empty() {
        problems.push("no reader on rt/lowcmd announced".to_owned());
    }
    for r in &readers {
        if r.type_name != dds_transport::topics::HG_LOWCMD_TYPE {
            problems.push(format!(
                "rt/lowcmd reader type `{}` (Unitree: `{}`)",
                r.type_name,
                dds_transport::topics::HG_LOWCMD_TYPE
            ));
        }
        // Unitree's SDK writes rt/lowcmd VOLATILE: a reader asking for more never matches it.
        if matches!(r.durability, Some(d) if d != Durability::Volatile) {
            problems.push(format!(
                "rt/lowcmd reader durability {:?} does not match Unitree's VOLATILE writer",
                r.durability
            ));
        }
    }
    let describe = |e: &dds_transport::DiscoveredEndpoint| {
        format!(
            "{} {} reliability={:?} history={:?} durability={:?} type_information={}",
            e.topic_name, e.type_name, e.reliability, e.history_depth, e.durability, e.has_type_information
        )
    };
    let status = if !problems.is_empty() {
        Status::Fail
    } else if writers.is_empty() {
        Status::Inconclusive
    } else {
        Status::Pass
    };
    let summary = if problems.is_empty() && !writers.is_empty() {
        "type names and QoS of rt/lowstate and rt/lowcmd match Unitree's SDK".to_owned()
    } else if problems.is_empty() {
        "LowState arrives but its writer was not seen in discovery data".to_owned()
    } else {
        problems.join("; ")
    };
    Ok(CheckResult::new(CheckId::DiscoveryTypesQos, status, summary)
        .with("lowstate_writers", writers.iter().map(|e| describe(e)).collect::<Vec<_>>())
        .with("lowcmd_readers", readers.iter().map(|e| describe(e)).collect::<Vec<_>>())
        .with("lowcmd_reader_matched_our_writer", target.command_reader_matched)
        .with("best_effort_writer", writers.iter().any(|w| w.reliability == Some(Reliability::BestEffort))))
}
