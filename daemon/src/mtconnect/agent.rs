//! The agent's state: the device model, the observation buffer and the tool assets, and the
//! documents it answers requests with. Time comes in as an argument: deterministic.

use super::assets::{self, Tool};
use super::buffer::{Buffer, Observation, OutOfRange, Value};
use super::error::{self, ErrorCode, RequestError};
use super::model::DeviceModel;
use super::observe::{self, MachineView};
use super::streams::{self, Sequences};
use super::xml::HeaderInfo;
use super::{devices, xpath};

/// Most tool assets: the offset table's 99 entries.
pub const ASSET_BUFFER_SIZE: usize = 99;

/// The agent of one device.
#[derive(Clone, Debug)]
pub struct Agent {
    model: DeviceModel,
    buffer: Buffer,
    tools: Vec<Tool>,
    instance_id: u64,
    sender: String,
    start_ns: u64,
}

impl From<OutOfRange> for RequestError {
    fn from(e: OutOfRange) -> RequestError {
        RequestError::new(ErrorCode::OutOfRange, e.to_string())
    }
}

/// A `/sample` answer: the document, the sequence to ask for next, and how many observations
/// it holds.
#[derive(Clone, Debug)]
pub struct SampleDoc {
    pub xml: Vec<u8>,
    pub next: u64,
    pub observations: usize,
}

impl Agent {
    /// A new agent: every data item starts UNAVAILABLE (sequence 1 onwards).
    pub fn new(
        model: DeviceModel,
        buffer_size: usize,
        instance_id: u64,
        sender: &str,
        now_ns: u64,
    ) -> Agent {
        let mut buffer = Buffer::new(model.items.len(), buffer_size);
        for i in 0..model.items.len() {
            buffer.push(now_ns, i, Value::Unavailable);
        }
        Agent {
            model,
            buffer,
            tools: Vec::new(),
            instance_id,
            sender: sender.into(),
            start_ns: now_ns,
        }
    }

    pub fn model(&self) -> &DeviceModel {
        &self.model
    }

    pub fn instance_id(&self) -> u64 {
        self.instance_id
    }

    pub fn buffer_size(&self) -> usize {
        self.buffer.capacity()
    }

    pub fn first_sequence(&self) -> u64 {
        self.buffer.first_sequence()
    }

    pub fn next_sequence(&self) -> u64 {
        self.buffer.next_sequence()
    }

    /// Writes what changed in the machine; returns the number of new observations.
    pub fn observe(&mut self, view: &MachineView, now_ns: u64) -> usize {
        observe::update(&mut self.buffer, &self.model, view, now_ns)
    }

    /// Replaces the tool assets: AssetChanged for each new or changed entry, AssetRemoved for
    /// each entry that is gone (zeroed).
    pub fn set_tools(&mut self, mut tools: Vec<Tool>, now_ns: u64) {
        let ids = &self.model.ids;
        let (changed, removed) = (ids.asset_changed, ids.asset_removed);
        for t in &mut tools {
            match self.tools.iter().find(|o| o.entry == t.entry) {
                Some(o) if o.radius_mm == t.radius_mm && o.lengths_mm == t.lengths_mm => {
                    t.changed_ns = o.changed_ns;
                }
                _ => {
                    t.changed_ns = now_ns;
                    self.buffer
                        .push(now_ns, changed, Value::Text(Tool::asset_id(t.entry)));
                }
            }
        }
        for o in &self.tools {
            if !tools.iter().any(|t| t.entry == o.entry) {
                self.buffer
                    .push(now_ns, removed, Value::Text(Tool::asset_id(o.entry)));
            }
        }
        self.tools = tools;
    }

    fn header(&self, now_ns: u64) -> HeaderInfo {
        HeaderInfo {
            creation_ns: now_ns,
            sender: self.sender.clone(),
            instance_id: self.instance_id,
            model_change_ns: self.start_ns,
            buffer_size: self.buffer.capacity(),
            asset_buffer_size: ASSET_BUFFER_SIZE,
            asset_count: self.tools.len(),
        }
    }

    fn sequences(&self, next: u64) -> Sequences {
        Sequences {
            first: self.buffer.first_sequence(),
            last: self.buffer.last_sequence(),
            next,
        }
    }

    /// The data items a `path` filter selects (`None`: every item).
    pub fn filter(&self, path: Option<&str>) -> Result<Option<Vec<usize>>, RequestError> {
        path.map(|p| xpath::select(&self.model, p)).transpose()
    }

    /// `/probe`.
    pub fn probe(&self, now_ns: u64) -> Vec<u8> {
        devices::write(&self.model, &self.header(now_ns))
    }

    /// `/current` (`at`: as of that sequence).
    pub fn current(
        &self,
        at: Option<u64>,
        filter: Option<&[usize]>,
        now_ns: u64,
    ) -> Result<Vec<u8>, RequestError> {
        let state = self.buffer.state_at(at)?;
        let obs: Vec<&Observation> = state
            .iter()
            .enumerate()
            .filter(|(i, _)| filter.is_none_or(|f| f.contains(i)))
            .flat_map(|(_, s)| s.shown())
            .collect();
        let next = at.map_or(self.buffer.next_sequence(), |a| a + 1);
        Ok(streams::write(
            &self.model,
            &self.header(now_ns),
            self.sequences(next),
            &obs,
        ))
    }

    /// `/sample`: up to `count` observations from `from` (default: the oldest held).
    pub fn sample(
        &self,
        from: Option<u64>,
        count: u64,
        filter: Option<&[usize]>,
        now_ns: u64,
    ) -> Result<SampleDoc, RequestError> {
        let from = from.unwrap_or(self.buffer.first_sequence());
        let wanted = |i: usize| filter.is_none_or(|f| f.contains(&i));
        let (obs, next) = self.buffer.sample(from, count as usize, wanted)?;
        let refs: Vec<&Observation> = obs.iter().collect();
        Ok(SampleDoc {
            xml: streams::write(
                &self.model,
                &self.header(now_ns),
                self.sequences(next),
                &refs,
            ),
            next,
            observations: obs.len(),
        })
    }

    /// `/assets`, or the assets named (ASSET_NOT_FOUND for an unknown id).
    pub fn assets(&self, ids: Option<&[String]>, now_ns: u64) -> Result<Vec<u8>, RequestError> {
        let tools: Vec<&Tool> = match ids {
            None => self.tools.iter().collect(),
            Some(ids) => ids
                .iter()
                .map(|id| {
                    self.tools
                        .iter()
                        .find(|t| Tool::asset_id(t.entry) == *id)
                        .ok_or_else(|| RequestError::new(ErrorCode::AssetNotFound, format!("no asset {id:?}: the tools are T01..T99, the non-zero entries of TAB0.KOR")))
                })
                .collect::<Result<_, _>>()?,
        };
        Ok(assets::write(
            &tools,
            &self.model.uuid,
            &self.header(now_ns),
        ))
    }

    /// The MTConnectError document of `e`.
    pub fn error(&self, e: &RequestError, now_ns: u64) -> Vec<u8> {
        error::write(e, &self.header(now_ns))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mtconnect::model::{AlarmInput, AxisDesc, IoDesc, MachineDesc};
    use crate::runtime::rt::{MachineState, Snapshot};

    fn agent() -> Agent {
        let m = MachineDesc {
            name: "mill".into(),
            uuid: "cncd-mill".into(),
            axes: vec![
                AxisDesc {
                    name: 'X',
                    rotary: false,
                    limit_neg: 1 << 1,
                    limit_pos: 1 << 2,
                },
                AxisDesc {
                    name: 'Y',
                    rotary: false,
                    limit_neg: 0,
                    limit_pos: 0,
                },
                AxisDesc {
                    name: 'C',
                    rotary: true,
                    limit_neg: 0,
                    limit_pos: 0,
                },
            ],
            cutting_speed: true,
            io: IoDesc {
                inputs: ["estop", "x_limit_neg", "x_limit_pos", "door", "air"]
                    .map(String::from)
                    .to_vec(),
                estop: 1,
                door: true,
                coolant: 1,
                alarms: vec![AlarmInput {
                    input: 4,
                    name: "air".into(),
                    message: "air pressure low".into(),
                    fault: false,
                }],
            },
        };
        Agent::new(
            DeviceModel::new(&m),
            64,
            7,
            "cncd",
            1_700_000_000_000_000_000,
        )
    }

    fn view<'a>(s: &'a Snapshot, names: &'a [char]) -> MachineView<'a> {
        MachineView {
            snap: s,
            program: Some("part.nc"),
            block: Some("N20 G1 X10 F500"),
            planner_alarm: None,
            axis_names: names,
            cutting_axis: Some(0),
        }
    }

    /// Writes `doc` where the suite's validation finds it (`CNC_MTCONNECT_DOCS`), if set.
    fn save(name: &str, doc: &[u8]) {
        if let Some(dir) = std::env::var_os("CNC_MTCONNECT_DOCS") {
            let dir = std::path::Path::new(&dir).join("unit");
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(dir.join(format!("{name}.xml")), doc).unwrap();
        }
    }

    #[test]
    fn a_fault_is_a_fault_condition_on_its_axis_and_normal_after_reset() {
        let mut a = agent();
        let names = ['X', 'Y', 'C'];
        let mut s = Snapshot::initial(3, kernel::AxesMm::default());
        s.state = MachineState::Running;
        s.progress.job = 1;
        s.progress.line = 2;
        s.axes.actual[0] = 12.5;
        assert!(a.observe(&view(&s, &names), 1_700_000_000_100_000_000) > 0);
        s.state = MachineState::Fault;
        s.alarm.fault = Some(hal::BusFault {
            axis: Some(1),
            node: Some(2),
            reason: hal::FaultReason::FollowingError,
        });
        a.observe(&view(&s, &names), 1_700_000_000_200_000_000);
        a.set_tools(
            vec![Tool {
                entry: 1,
                radius_mm: 5.0,
                lengths_mm: vec![('Z', 120.0)],
                changed_ns: 0,
            }],
            1_700_000_000_250_000_000,
        );
        let cur =
            String::from_utf8(a.current(None, None, 1_700_000_000_300_000_000).unwrap()).unwrap();
        save("current_fault", cur.as_bytes());
        assert!(cur.contains("<Fault dataItemId=\"y_cond\""), "{cur}");
        assert!(cur.contains("nativeCode=\"following_error\""), "{cur}");
        assert!(cur.contains("<Execution dataItemId=\"exec\""), "{cur}");
        s.state = MachineState::Idle;
        s.alarm.fault = None;
        a.observe(&view(&s, &names), 1_700_000_000_400_000_000);
        let cur =
            String::from_utf8(a.current(None, None, 1_700_000_000_500_000_000).unwrap()).unwrap();
        assert!(!cur.contains("<Fault"), "{cur}");
        save("current_normal", cur.as_bytes());
        save("probe", &a.probe(1));
        let s = a.sample(None, 1000, None, 1).unwrap();
        save("sample", &s.xml);
        save("assets", &a.assets(None, 1).unwrap());
        let f = a.filter(Some("//Linear[@name=\"Y\"]")).unwrap();
        save(
            "sample_filtered",
            &a.sample(None, 10, f.as_deref(), 1).unwrap().xml,
        );
        let e = a.assets(Some(&["T07".into()]), 1).unwrap_err();
        save("error", &a.error(&e, 1));
        save(
            "sample_empty",
            &a.sample(Some(a.next_sequence()), 10, None, 1).unwrap().xml,
        );
    }

    #[test]
    fn the_inputs_and_outputs_are_the_door_the_coolant_the_travel_and_the_alarms() {
        let mut a = agent();
        let names = ['X', 'Y', 'C'];
        let mut s = Snapshot::initial(3, kernel::AxesMm::default());
        // At rest: the chain and the door closed, no switch, no alarm, the coolant off.
        s.io.inputs = hal::io::IoBits(0b01001);
        a.observe(&view(&s, &names), 1_700_000_000_100_000_000);
        let cur = String::from_utf8(a.current(None, None, 1).unwrap()).unwrap();
        for want in [
            ">ARMED</EmergencyStop>",
            ">CLOSED</DoorState>",
            "subType=\"CONTROL\">OFF</PowerState>",
            "<Normal dataItemId=\"x_travel\"",
            "<Normal dataItemId=\"machine_alarms\"",
        ] {
            assert!(cur.contains(want), "{want}: {cur}");
        }
        // The chain open with the door, X's positive switch reached, the air alarm, M8.
        s.io.inputs = hal::io::IoBits(0b10100);
        s.io.estop_open = true;
        s.io.door_open = true;
        s.io.limits = hal::io::IoBits(0b00100);
        s.io.alarms = hal::io::IoBits(0b10000);
        s.io.outputs = hal::io::IoBits(0b1);
        s.state = MachineState::Fault;
        s.alarm.fault = Some(hal::BusFault {
            axis: None,
            node: None,
            reason: hal::FaultReason::EmergencyStop { input: 0 },
        });
        a.observe(&view(&s, &names), 1_700_000_000_200_000_000);
        let cur = String::from_utf8(a.current(None, None, 1).unwrap()).unwrap();
        save("current_io", cur.as_bytes());
        for want in [
            ">TRIGGERED</EmergencyStop>",
            ">OPEN</DoorState>",
            "subType=\"CONTROL\">ON</PowerState>",
            "nativeCode=\"emergency_stop\"",
            "nativeCode=\"limit_switch\"",
            "qualifier=\"HIGH\"",
            "type=\"POSITION\"",
            "nativeCode=\"air\"",
            "air pressure low</Warning>",
            "(input estop)",
        ] {
            assert!(cur.contains(want), "{want}: {cur}");
        }
        // After Reset the switch is acknowledged but still reached: a Warning; the rest clear.
        s.io = Default::default();
        s.io.inputs = hal::io::IoBits(0b01101);
        s.io.limits = hal::io::IoBits(0b00100);
        s.io.limits_acknowledged = hal::io::IoBits(0b00100);
        s.state = MachineState::Idle;
        s.alarm.fault = None;
        a.observe(&view(&s, &names), 1_700_000_000_300_000_000);
        let cur = String::from_utf8(a.current(None, None, 1).unwrap()).unwrap();
        save("current_io_reset", cur.as_bytes());
        assert!(cur.contains(">ARMED</EmergencyStop>"), "{cur}");
        assert!(cur.contains("<Warning dataItemId=\"x_travel\""), "{cur}");
        assert!(!cur.contains("<Fault"), "{cur}");
        save("probe_io", &a.probe(1));
    }

    #[test]
    fn current_at_and_sample_refuse_sequences_outside_the_buffer() {
        let a = agent();
        let e = a.current(Some(a.next_sequence()), None, 1).unwrap_err();
        assert_eq!(e.code, ErrorCode::OutOfRange);
        let e = a
            .sample(Some(a.next_sequence() + 1), 10, None, 1)
            .unwrap_err();
        assert_eq!(e.code, ErrorCode::OutOfRange);
        assert_eq!(
            a.filter(Some("//Nothing")).unwrap_err().code,
            ErrorCode::InvalidPath
        );
        assert_eq!(
            a.filter(Some("Linear")).unwrap_err().code,
            ErrorCode::InvalidPath
        );
        let f = a
            .filter(Some("//DataItem[@category=\"CONDITION\"]"))
            .unwrap()
            .unwrap();
        assert!(
            f.iter()
                .all(|&i| a.model().items[i].category
                    == crate::mtconnect::model::Category::Condition)
        );
    }
}
