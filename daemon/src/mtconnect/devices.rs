//! The Devices document (`/probe`): the device model.

use super::model::{Category, DeviceModel};
use super::xml::{HeaderInfo, SCHEMA_VERSION, Xml, attrs};

/// `MTConnectDevices` of `model`.
pub fn write(model: &DeviceModel, h: &HeaderInfo) -> Vec<u8> {
    let mut x = Xml::new();
    x.root("Devices");
    let mut a = h.common();
    a.push(("bufferSize", h.buffer_size.to_string()));
    a.push(("assetBufferSize", h.asset_buffer_size.to_string()));
    a.push(("assetCount", h.asset_count.to_string()));
    x.empty("Header", &attrs(&a));
    x.open("Devices", &[]);
    component(&mut x, model, 0);
    x.close("Devices");
    x.close("MTConnectDevices");
    x.finish()
}

fn component(x: &mut Xml, m: &DeviceModel, c: usize) {
    let comp = &m.components[c];
    let mut a: Vec<(&str, &str)> = vec![("id", &comp.id)];
    if let Some(n) = &comp.name {
        a.push(("name", n));
    }
    if c == 0 {
        a.push(("uuid", &m.uuid));
        a.push(("mtconnectVersion", SCHEMA_VERSION));
    }
    x.open(comp.element, &a);
    if c == 0 {
        x.text(
            "Description",
            &[("manufacturer", "cnc"), ("model", "cncd")],
            "CNC controller cncd",
        );
    }
    if !comp.items.is_empty() {
        x.open("DataItems", &[]);
        for &i in &comp.items {
            data_item(x, m, i);
        }
        x.close("DataItems");
    }
    if !comp.children.is_empty() {
        x.open("Components", &[]);
        for &k in &comp.children {
            component(x, m, k);
        }
        x.close("Components");
    }
    x.close(comp.element);
}

fn data_item(x: &mut Xml, m: &DeviceModel, i: usize) {
    let d = &m.items[i];
    let mut a: Vec<(&str, &str)> = vec![
        ("id", &d.id),
        ("category", d.category.as_str()),
        ("type", d.kind),
    ];
    if let Some(s) = d.sub_type {
        a.push(("subType", s));
    }
    if let Some(u) = d.units {
        a.push(("units", u));
    }
    if d.category == Category::Sample && d.three_d {
        a.push(("coordinateSystem", "MACHINE"));
    }
    x.empty("DataItem", &a);
}
