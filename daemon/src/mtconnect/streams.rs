//! The Streams document (`/current`, `/sample`): observations grouped by component, then by
//! category (Samples, Events, Condition), in sequence order.

use super::buffer::{Level, Observation, Value};
use super::model::{Category, DeviceModel};
use super::xml::{HeaderInfo, Xml, attrs, number, timestamp};

/// The sequence fields of a Streams header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sequences {
    pub first: u64,
    pub last: u64,
    pub next: u64,
}

/// `MTConnectStreams` with `obs` (any order; sorted here).
pub fn write(model: &DeviceModel, h: &HeaderInfo, seq: Sequences, obs: &[&Observation]) -> Vec<u8> {
    let mut x = Xml::new();
    x.root("Streams");
    let mut a = h.common();
    a.push(("bufferSize", h.buffer_size.to_string()));
    a.push(("nextSequence", seq.next.to_string()));
    a.push(("firstSequence", seq.first.to_string()));
    a.push(("lastSequence", seq.last.to_string()));
    x.empty("Header", &attrs(&a));
    let mut obs: Vec<&Observation> = obs.to_vec();
    obs.sort_by_key(|o| o.sequence);
    x.open("Streams", &[]);
    if !obs.is_empty() {
        x.open(
            "DeviceStream",
            &[("name", &model.name), ("uuid", &model.uuid)],
        );
        for (c, comp) in model.components.iter().enumerate() {
            let mine: Vec<&Observation> = obs
                .iter()
                .copied()
                .filter(|o| model.items[o.item].component == c)
                .collect();
            if mine.is_empty() {
                continue;
            }
            let mut ca: Vec<(&str, &str)> =
                vec![("component", comp.element), ("componentId", &comp.id)];
            if let Some(n) = &comp.name {
                ca.push(("name", n));
            }
            x.open("ComponentStream", &ca);
            for (cat, group) in [
                (Category::Sample, "Samples"),
                (Category::Event, "Events"),
                (Category::Condition, "Condition"),
            ] {
                let of_cat: Vec<&&Observation> = mine
                    .iter()
                    .filter(|o| model.items[o.item].category == cat)
                    .collect();
                if of_cat.is_empty() {
                    continue;
                }
                x.open(group, &[]);
                for o in of_cat {
                    observation(&mut x, model, o);
                }
                x.close(group);
            }
            x.close("ComponentStream");
        }
        x.close("DeviceStream");
    }
    x.close("Streams");
    x.close("MTConnectStreams");
    x.finish()
}

fn observation(x: &mut Xml, m: &DeviceModel, o: &Observation) {
    let d = &m.items[o.item];
    let ts = timestamp(o.time_ns);
    let seq = o.sequence.to_string();
    let mut a: Vec<(&str, &str)> = vec![
        ("dataItemId", &d.id),
        ("timestamp", &ts),
        ("sequence", &seq),
    ];
    if d.category == Category::Condition {
        a.push(("type", d.kind));
        let (el, text) = match &o.value {
            Value::Condition(c) => {
                if let Some(code) = &c.native_code {
                    a.push(("nativeCode", code));
                    // Warning and Fault name the alarm they raise: one per code.
                    if c.level != Level::Normal {
                        a.push(("conditionId", code));
                    }
                }
                if let (Some(q), false) = (c.qualifier, c.level == Level::Normal) {
                    a.push(("qualifier", q));
                }
                (c.level.element(), c.message.as_str())
            }
            _ => ("Unavailable", ""),
        };
        return x.text(el, &a, text);
    }
    if let Some(s) = d.sub_type {
        a.push(("subType", s));
    }
    if matches!(d.kind, "ASSET_CHANGED" | "ASSET_REMOVED") {
        a.push(("assetType", "CuttingTool"));
    }
    let text = match &o.value {
        Value::Number(v) => number(*v),
        Value::Vector(v) => v.map(number).join(" "),
        Value::Text(t) => t.clone(),
        Value::Unavailable | Value::Condition(_) => "UNAVAILABLE".into(),
    };
    x.text(d.element, &a, &text);
}
