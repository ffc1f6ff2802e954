//! The Assets document (`/assets`): the entries of the offset table TAB0.KOR (SPEC §3) as
//! `CuttingTool` assets, each with its radius (as the cutting diameter) and its lengths.

use super::xml::{HeaderInfo, Xml, attrs, number, timestamp};

/// One offset entry as a tool: entry `01` is asset `T01`.
#[derive(Clone, Debug, PartialEq)]
pub struct Tool {
    /// Entry number 1..=99 (the program's `D`/tool number).
    pub entry: u8,
    pub radius_mm: f64,
    /// Length per axis letter (axes 1..4 of the machine; zeros left out).
    pub lengths_mm: Vec<(char, f64)>,
    /// When this entry last changed (or the agent started), ns since the Unix epoch.
    pub changed_ns: u64,
}

impl Tool {
    /// The asset id of entry `entry`.
    pub fn asset_id(entry: u8) -> String {
        format!("T{entry:02}")
    }
}

/// `MTConnectAssets` with `tools`.
pub fn write(tools: &[&Tool], device_uuid: &str, h: &HeaderInfo) -> Vec<u8> {
    let mut x = Xml::new();
    x.root("Assets");
    let mut a = h.common();
    a.push(("assetBufferSize", h.asset_buffer_size.to_string()));
    a.push(("assetCount", h.asset_count.to_string()));
    x.empty("Header", &attrs(&a));
    x.open("Assets", &[]);
    for t in tools {
        tool(&mut x, t, device_uuid);
    }
    x.close("Assets");
    x.close("MTConnectAssets");
    x.finish()
}

fn tool(x: &mut Xml, t: &Tool, device_uuid: &str) {
    let id = Tool::asset_id(t.entry);
    let ts = timestamp(t.changed_ns);
    let n = t.entry.to_string();
    x.open(
        "CuttingTool",
        &[
            ("assetId", &id),
            ("timestamp", &ts),
            ("deviceUuid", device_uuid),
            ("serialNumber", &id),
            ("toolId", &id),
        ],
    );
    x.text(
        "Description",
        &[],
        &format!("offset table TAB0.KOR entry {:02}", t.entry),
    );
    x.open("CuttingToolLifeCycle", &[]);
    x.open("CutterStatus", &[]);
    x.text("Status", &[], "AVAILABLE");
    x.close("CutterStatus");
    x.text("ProgramToolNumber", &[], &n);
    let mut measurements: Vec<(&str, String, String)> = Vec::new();
    if t.radius_mm != 0.0 {
        measurements.push(("CuttingDiameterMax", "DC".into(), number(2.0 * t.radius_mm)));
    }
    for (axis, l) in &t.lengths_mm {
        // One functional length per axis: the code names the axis it applies to.
        measurements.push(("FunctionalLength", format!("LF{axis}"), number(*l)));
    }
    if !measurements.is_empty() {
        x.open("Measurements", &[]);
        for (el, code, v) in &measurements {
            x.text(el, &[("code", code), ("units", "MILLIMETER")], v);
        }
        x.close("Measurements");
    }
    x.close("CuttingToolLifeCycle");
    x.close("CuttingTool");
}
