//! Fuzzing entry of the agent's request door (`fuzz/`, issue #50): arbitrary bytes as the
//! request line's path and query (split at the first `?`), parsed as the agent parses a GET,
//! and any XPath it carries selected on a mill's device model. Must never panic; a selection
//! names items of the model only.

use super::model::{AxisDesc, DeviceModel, IoDesc, MachineDesc};
use super::request::{self, Request};
use super::xpath;

fn mill() -> MachineDesc {
    let axis = |name| AxisDesc {
        name,
        rotary: false,
        limit_neg: 1,
        limit_pos: 2,
    };
    MachineDesc {
        name: "cncd".into(),
        uuid: "fuzz".into(),
        axes: vec![axis('X'), axis('Y'), axis('Z')],
        cutting_speed: true,
        io: IoDesc {
            inputs: vec!["estop".into(), "door".into()],
            estop: 1,
            door: true,
            coolant: 1,
            alarms: Vec::new(),
        },
    }
}

pub fn fuzz_entry(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let (path, query) = text.split_once('?').unwrap_or((&text, ""));
    let model = DeviceModel::new(&mill());
    let Ok(req) = request::parse(path, query, "cncd", 1024) else {
        return;
    };
    let xp = match &req {
        Request::Current { path, .. } | Request::Sample { path, .. } => path.as_deref(),
        _ => None,
    };
    for p in [xp, Some(path)].into_iter().flatten() {
        if let Ok(items) = xpath::select(&model, p) {
            assert!(items.iter().all(|&i| i < model.items.len()));
        }
    }
}
