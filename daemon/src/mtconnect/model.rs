//! The MTConnect device model of the machine (docs/mtconnect.md *Device model*): components
//! and data items built from the machine's configuration, with the ids the feed writes to.
//!
//! Types, subtypes and units are the standard's (MTConnect 2.5, Part 2 Devices): positions in
//! MILLIMETER (DEGREE on rotary axes, `ANGLE`), feed in MILLIMETER/SECOND, speeds in
//! REVOLUTION/MINUTE, overrides in PERCENT. The machine's inputs and outputs (`[io]`) add the
//! Door (`DOOR_STATE`), the Coolant system (`POWER_STATE` CONTROL), a `POSITION` condition per
//! axis with limit switches and the machine's alarm inputs (a `SYSTEM` condition of the device).

/// What the device model is built from (the configuration, read once at start).
#[derive(Clone, Debug, PartialEq)]
pub struct MachineDesc {
    /// Device name (`mtconnect.device_name`).
    pub name: String,
    /// Device uuid (`mtconnect.device_uuid`): stable across restarts.
    pub uuid: String,
    /// Axes in machine order.
    pub axes: Vec<AxisDesc>,
    /// The machine has constant cutting speed (KŘR) with a controlling axis: the spindle
    /// publishes the cutting speed at the tool.
    pub cutting_speed: bool,
    /// The machine's inputs and outputs.
    pub io: IoDesc,
}

/// The machine's inputs and outputs as the agent shows them (from `[io]`, in its order: bit k
/// of the snapshot's `io.inputs` / `io.outputs` is input / output k).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IoDesc {
    /// Input names (messages and nativeCodes name them).
    pub inputs: Vec<String>,
    /// The e-stop chain's inputs (bit k: input k).
    pub estop: u64,
    /// The machine has a door interlock input: a `Door` component with `DOOR_STATE`.
    pub door: bool,
    /// The outputs that switch the coolant (bit k: output k): a `Coolant` system with
    /// `POWER_STATE` CONTROL, ON while one of them is on.
    pub coolant: u64,
    /// Alarm inputs (`function = "alarm"`): CONDITIONs of the device's `SYSTEM` item.
    pub alarms: Vec<AlarmInput>,
}

/// One alarm input.
#[derive(Clone, Debug, PartialEq)]
pub struct AlarmInput {
    /// Its index among the inputs.
    pub input: usize,
    /// Its name: the condition's nativeCode.
    pub name: String,
    /// The configured text.
    pub message: String,
    /// Severity `fault` (Fault; the machine stops) or `warning` (Warning).
    pub fault: bool,
}

/// One axis of the machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AxisDesc {
    /// Program letter (`X`, `Z`, `C`...).
    pub name: char,
    /// Rotary axis (degrees): a `Rotary` component with `ANGLE`; else `Linear` with `POSITION`.
    pub rotary: bool,
    /// Its hardware limit switches, negative and positive side (bit k: input k): with any,
    /// the axis has a `POSITION` (or `ANGLE`) condition, Fault while one is reached.
    pub limit_neg: u64,
    pub limit_pos: u64,
}

/// Data item category.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Category {
    Sample,
    Event,
    Condition,
}

impl Category {
    pub fn as_str(self) -> &'static str {
        match self {
            Category::Sample => "SAMPLE",
            Category::Event => "EVENT",
            Category::Condition => "CONDITION",
        }
    }
}

/// One data item of the model.
#[derive(Clone, Debug, PartialEq)]
pub struct DataItem {
    pub id: String,
    pub category: Category,
    /// The standard's type (`POSITION`).
    pub kind: &'static str,
    /// The element name of its observations in Streams (`Position`).
    pub element: &'static str,
    pub sub_type: Option<&'static str>,
    pub units: Option<&'static str>,
    /// Samples of three values (`PATH_POSITION`).
    pub three_d: bool,
    /// Index of the component it belongs to in [`DeviceModel::components`].
    pub component: usize,
}

/// One component (the device itself is component 0).
#[derive(Clone, Debug, PartialEq)]
pub struct Component {
    /// Element name in Devices and `component` attribute in Streams (`Linear`).
    pub element: &'static str,
    pub id: String,
    pub name: Option<String>,
    pub parent: Option<usize>,
    pub children: Vec<usize>,
    pub items: Vec<usize>,
}

/// Indices (into [`DeviceModel::items`]) of the data items the feed writes: one concern, a
/// lookup table with one entry per data item (per-axis and spindle items grouped).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ItemIds {
    pub availability: usize,
    pub asset_changed: usize,
    pub asset_removed: usize,
    pub emergency_stop: usize,
    pub controller_mode: usize,
    pub system: usize,
    pub communications: usize,
    pub execution: usize,
    pub program: usize,
    pub block: usize,
    pub line_number: usize,
    /// `TOOL_NUMBER` and `MESSAGE` of the Path: the tool a manual tool change (M6) holds for
    /// and its prompt (UNAVAILABLE otherwise).
    pub tool_number: usize,
    pub message: usize,
    pub path_feedrate: usize,
    pub feedrate_override: usize,
    pub rapid_override: usize,
    pub path_position: usize,
    pub motion: usize,
    pub logic: usize,
    pub axes: Vec<AxisIds>,
    pub spindle: SpindleIds,
    pub cutting_speed: Option<usize>,
    /// `DOOR_STATE` of the Door (with a door input).
    pub door_state: Option<usize>,
    /// `POWER_STATE` CONTROL of the Coolant system (with a coolant output).
    pub coolant: Option<usize>,
    /// The device's `SYSTEM` condition: the alarm inputs (with any).
    pub machine_alarms: Option<usize>,
}

/// The data items of one axis.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxisIds {
    pub actual: usize,
    pub commanded: usize,
    pub condition: usize,
    /// The travel condition (`POSITION`/`ANGLE`): its limit switches (with any).
    pub travel: Option<usize>,
}

/// The data items of the spindle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpindleIds {
    pub actual: usize,
    pub commanded: usize,
    pub override_pct: usize,
    pub mode: usize,
    pub condition: usize,
}

/// The device: components, data items and the feed's ids.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceModel {
    pub name: String,
    pub uuid: String,
    pub components: Vec<Component>,
    pub items: Vec<DataItem>,
    pub ids: ItemIds,
    /// The inputs and outputs the feed reads (names, masks, alarm texts).
    pub io: IoDesc,
    /// Per axis, its limit switches (negative, positive side).
    pub limits: Vec<(u64, u64)>,
}

/// The spec of one data item before it gets its component.
struct Item {
    id: String,
    category: Category,
    kind: &'static str,
    element: &'static str,
    sub_type: Option<&'static str>,
    units: Option<&'static str>,
}

fn sample(id: &str, kind: &'static str, element: &'static str, units: &'static str) -> Item {
    Item {
        id: id.into(),
        category: Category::Sample,
        kind,
        element,
        sub_type: None,
        units: Some(units),
    }
}

fn event(id: &str, kind: &'static str, element: &'static str) -> Item {
    Item {
        id: id.into(),
        category: Category::Event,
        kind,
        element,
        sub_type: None,
        units: None,
    }
}

fn condition(id: &str, kind: &'static str) -> Item {
    Item {
        id: id.into(),
        category: Category::Condition,
        kind,
        element: "",
        sub_type: None,
        units: None,
    }
}

impl Item {
    fn sub(mut self, s: &'static str) -> Item {
        self.sub_type = Some(s);
        self
    }
}

impl DeviceModel {
    fn component(
        &mut self,
        parent: Option<usize>,
        element: &'static str,
        id: &str,
        name: Option<&str>,
    ) -> usize {
        let c = self.components.len();
        self.components.push(Component {
            element,
            id: id.into(),
            name: name.map(str::to_string),
            parent,
            children: Vec::new(),
            items: Vec::new(),
        });
        if let Some(p) = parent {
            self.components[p].children.push(c);
        }
        c
    }

    fn item(&mut self, component: usize, i: Item) -> usize {
        let n = self.items.len();
        self.items.push(DataItem {
            three_d: i.kind == "PATH_POSITION",
            id: i.id,
            category: i.category,
            kind: i.kind,
            element: i.element,
            sub_type: i.sub_type,
            units: i.units,
            component,
        });
        self.components[component].items.push(n);
        n
    }

    /// The model of `m`: Device › Axes (Linear/Rotary per axis, the spindle), Controller ›
    /// Path, and with the machine's I/O Systems › Coolant and Door.
    pub fn new(m: &MachineDesc) -> DeviceModel {
        let mut d = DeviceModel {
            name: m.name.clone(),
            uuid: m.uuid.clone(),
            components: Vec::new(),
            items: Vec::new(),
            ids: ItemIds::default(),
            io: m.io.clone(),
            limits: m.axes.iter().map(|a| (a.limit_neg, a.limit_pos)).collect(),
        };
        let dev = d.component(None, "Device", "dev", Some(&m.name));
        d.ids.availability = d.item(dev, event("avail", "AVAILABILITY", "Availability"));
        d.ids.asset_changed = d.item(dev, event("asset_chg", "ASSET_CHANGED", "AssetChanged"));
        d.ids.asset_removed = d.item(dev, event("asset_rem", "ASSET_REMOVED", "AssetRemoved"));
        if !m.io.alarms.is_empty() {
            d.ids.machine_alarms = Some(d.item(dev, condition("machine_alarms", "SYSTEM")));
        }
        let axes = d.component(Some(dev), "Axes", "axes", None);
        for a in &m.axes {
            let ids = d.axis(axes, *a);
            d.ids.axes.push(ids);
        }
        d.ids.spindle = d.spindle(axes);
        if m.cutting_speed {
            let s = d.components.len() - 1;
            let id = d.item(
                s,
                sample(
                    "cut_speed",
                    "CUTTING_SPEED",
                    "CuttingSpeed",
                    "MILLIMETER/SECOND",
                )
                .sub("ACTUAL"),
            );
            d.ids.cutting_speed = Some(id);
        }
        d.controller(dev);
        if m.io.coolant != 0 {
            let systems = d.component(Some(dev), "Systems", "systems", None);
            let c = d.component(Some(systems), "Coolant", "coolant", Some("coolant"));
            d.ids.coolant = Some(d.item(
                c,
                event("coolant_state", "POWER_STATE", "PowerState").sub("CONTROL"),
            ));
        }
        if m.io.door {
            let c = d.component(Some(dev), "Door", "door", Some("door"));
            d.ids.door_state = Some(d.item(c, event("door_state", "DOOR_STATE", "DoorState")));
        }
        d
    }

    fn axis(&mut self, axes: usize, a: AxisDesc) -> AxisIds {
        let name = a.name.to_string();
        let id = a.name.to_ascii_lowercase().to_string();
        let (element, kind, obs, units) = if a.rotary {
            ("Rotary", "ANGLE", "Angle", "DEGREE")
        } else {
            ("Linear", "POSITION", "Position", "MILLIMETER")
        };
        let c = self.component(Some(axes), element, &id, Some(&name));
        let actual = self.item(
            c,
            sample(&format!("{id}_act"), kind, obs, units).sub("ACTUAL"),
        );
        let commanded = self.item(
            c,
            sample(&format!("{id}_cmd"), kind, obs, units).sub("COMMANDED"),
        );
        let condition = self.item(c, condition(&format!("{id}_cond"), "ACTUATOR"));
        let travel = (a.limit_neg | a.limit_pos != 0)
            .then(|| self.item(c, self::condition(&format!("{id}_travel"), kind)));
        AxisIds {
            actual,
            commanded,
            condition,
            travel,
        }
    }

    fn spindle(&mut self, axes: usize) -> SpindleIds {
        let c = self.component(Some(axes), "Rotary", "spindle", Some("S"));
        let rpm = "REVOLUTION/MINUTE";
        SpindleIds {
            actual: self.item(
                c,
                sample("s_speed", "ROTARY_VELOCITY", "RotaryVelocity", rpm).sub("ACTUAL"),
            ),
            commanded: self.item(
                c,
                sample("s_cmd", "ROTARY_VELOCITY", "RotaryVelocity", rpm).sub("COMMANDED"),
            ),
            override_pct: self.item(
                c,
                event(
                    "s_ovr",
                    "ROTARY_VELOCITY_OVERRIDE",
                    "RotaryVelocityOverride",
                ),
            ),
            mode: self.item(c, event("s_mode", "ROTARY_MODE", "RotaryMode")),
            condition: self.item(c, condition("s_cond", "ACTUATOR")),
        }
    }

    fn controller(&mut self, dev: usize) {
        let c = self.component(Some(dev), "Controller", "ctrl", Some("controller"));
        self.ids.emergency_stop = self.item(c, event("estop", "EMERGENCY_STOP", "EmergencyStop"));
        self.ids.controller_mode = self.item(c, event("mode", "CONTROLLER_MODE", "ControllerMode"));
        self.ids.system = self.item(c, condition("ctrl_system", "SYSTEM"));
        self.ids.communications = self.item(c, condition("ctrl_comms", "COMMUNICATIONS"));
        let p = self.component(Some(c), "Path", "path", Some("path"));
        self.ids.execution = self.item(p, event("exec", "EXECUTION", "Execution"));
        self.ids.program = self.item(p, event("program", "PROGRAM", "Program"));
        self.ids.block = self.item(p, event("block", "BLOCK", "Block"));
        self.ids.line_number = self.item(
            p,
            event("line", "LINE_NUMBER", "LineNumber").sub("ABSOLUTE"),
        );
        self.ids.tool_number = self.item(p, event("tool", "TOOL_NUMBER", "ToolNumber"));
        self.ids.message = self.item(p, event("message", "MESSAGE", "Message"));
        self.ids.path_feedrate = self.item(
            p,
            sample("feed", "PATH_FEEDRATE", "PathFeedrate", "MILLIMETER/SECOND").sub("ACTUAL"),
        );
        self.ids.feedrate_override = self.item(
            p,
            event("feed_ovr", "PATH_FEEDRATE_OVERRIDE", "PathFeedrateOverride").sub("PROGRAMMED"),
        );
        self.ids.rapid_override = self.item(
            p,
            event(
                "rapid_ovr",
                "PATH_FEEDRATE_OVERRIDE",
                "PathFeedrateOverride",
            )
            .sub("RAPID"),
        );
        self.ids.path_position = self.item(
            p,
            sample("path_pos", "PATH_POSITION", "PathPosition", "MILLIMETER_3D").sub("ACTUAL"),
        );
        self.ids.motion = self.item(p, condition("motion", "MOTION_PROGRAM"));
        self.ids.logic = self.item(p, condition("logic", "LOGIC_PROGRAM"));
    }

    /// The data item with id `id`.
    pub fn item_by_id(&self, id: &str) -> Option<usize> {
        self.items.iter().position(|i| i.id == id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lathe() -> MachineDesc {
        MachineDesc {
            name: "lathe".into(),
            uuid: "u-1".into(),
            axes: vec![
                AxisDesc {
                    name: 'X',
                    rotary: false,
                    limit_neg: 1 << 1,
                    limit_pos: 1 << 2,
                },
                AxisDesc {
                    name: 'Z',
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
                inputs: vec![
                    "estop".into(),
                    "x_neg".into(),
                    "x_pos".into(),
                    "door".into(),
                ],
                estop: 1,
                door: true,
                coolant: 1,
                alarms: vec![AlarmInput {
                    input: 4,
                    name: "lube".into(),
                    message: "lubrication low".into(),
                    fault: false,
                }],
            },
        }
    }

    #[test]
    fn ids_are_unique_and_every_item_has_its_component() {
        let d = DeviceModel::new(&lathe());
        let mut ids: Vec<&str> = d.items.iter().map(|i| i.id.as_str()).collect();
        ids.extend(d.components.iter().map(|c| c.id.as_str()));
        let n = ids.len();
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids.len(), n);
        for (i, it) in d.items.iter().enumerate() {
            assert!(d.components[it.component].items.contains(&i));
        }
        assert_eq!(d.ids.axes.len(), 3);
        assert_eq!(d.items[d.ids.axes[2].actual].kind, "ANGLE");
        assert!(d.ids.cutting_speed.is_some());
        let travel = d.ids.axes[0].travel.unwrap();
        assert_eq!(
            (d.items[travel].category, d.items[travel].kind),
            (Category::Condition, "POSITION")
        );
        assert_eq!(d.ids.axes[1].travel, None);
        let door = d.ids.door_state.unwrap();
        assert_eq!(d.components[d.items[door].component].element, "Door");
        let coolant = d.ids.coolant.unwrap();
        assert_eq!(d.components[d.items[coolant].component].element, "Coolant");
        assert_eq!(d.items[d.ids.machine_alarms.unwrap()].component, 0);
    }
}
