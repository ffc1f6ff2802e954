//! Checks of `[io]` (docs/io.md): counts, names, where each point is wired on the configured
//! bus, one function per input and one binding per output, M functions free to take.

use super::InvalidConfig;
use super::axes::AxisConfig;
use super::bus::BusConfig;
use super::io::{
    InputConfig, InputFunction, IoSection, ModuleConfig, OutputConfig, RESERVED_M, Wiring, parse_m,
};

/// What the checks read of the rest of the configuration.
pub struct IoContext<'a> {
    pub bus: &'a BusConfig,
    pub axes: &'a [AxisConfig],
    /// M codes of the gear table (`[kr.gears]`).
    pub gear_m: Vec<u16>,
}

/// The wiring keys of one point, as given.
struct PointKeys<'a> {
    key: String,
    node_id: Option<u8>,
    drive: Option<&'a str>,
    bit: Option<u8>,
    input: bool,
}

impl IoSection {
    /// The whole section; the first mistake found, naming its key.
    pub fn validate(&self, ctx: &IoContext) -> Result<(), InvalidConfig> {
        let max = hal::io::MAX_IO;
        for (what, n) in [
            ("io.inputs", self.inputs.len()),
            ("io.outputs", self.outputs.len()),
        ] {
            if n > max {
                return Err(bad(
                    what.into(),
                    format!("{n} listed, at most {max} are supported"),
                ));
            }
        }
        self.check_names()?;
        let mut seen: Vec<(Wiring, String)> = Vec::new();
        for (i, inp) in self.inputs.iter().enumerate() {
            let key = format!("io.inputs[{i}]");
            let w = self.wiring(ctx, &inp.point_keys(&key))?;
            no_twice(&mut seen, w, &key, "input")?;
            check_input(inp, w, ctx, &key)?;
        }
        let mut seen: Vec<(Wiring, String)> = Vec::new();
        for (i, out) in self.outputs.iter().enumerate() {
            let key = format!("io.outputs[{i}]");
            let w = self.wiring(ctx, &out.point_keys(&key))?;
            no_twice(&mut seen, w, &key, "output")?;
            check_output(out, ctx, &key)?;
        }
        if self.module_consumer_timeout_ms == 0 {
            return Err(bad(
                "io.module_consumer_timeout_ms".into(),
                "0 would let a module keep its outputs when the controller dies".into(),
            ));
        }
        Ok(())
    }

    /// Names are non-empty and unique over inputs and outputs.
    fn check_names(&self) -> Result<(), InvalidConfig> {
        let names = self
            .inputs
            .iter()
            .map(|p| &p.name)
            .enumerate()
            .map(|(i, n)| (format!("io.inputs[{i}].name"), n))
            .chain(
                self.outputs
                    .iter()
                    .map(|p| &p.name)
                    .enumerate()
                    .map(|(i, n)| (format!("io.outputs[{i}].name"), n)),
            );
        let mut seen: Vec<&String> = Vec::new();
        for (key, name) in names {
            let ok = !name.is_empty()
                && name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
            if !ok {
                return Err(bad(
                    key,
                    format!("'{name}': a name is letters, digits, '_' and '-'"),
                ));
            }
            if seen.contains(&name) {
                return Err(InvalidConfig::Duplicate {
                    key,
                    detail: format!("'{name}' is already the name of another input or output"),
                });
            }
            seen.push(name);
        }
        Ok(())
    }

    /// Where a point is wired, checked against the bus: a module node that is no drive, a
    /// drive of an axis, a bit within its word.
    fn wiring(&self, ctx: &IoContext, p: &PointKeys) -> Result<Wiring, InvalidConfig> {
        let can = matches!(ctx.bus, BusConfig::Can(_));
        match (p.node_id, p.drive) {
            (Some(_), Some(_)) => Err(bad(
                format!("{}.drive", p.key),
                "give node_id (an I/O module) or drive (a drive's own I/O), not both".into(),
            )),
            (Some(node), None) => {
                if !can {
                    return Err(bad(
                        format!("{}.node_id", p.key),
                        format!(
                            "node {node} is a CiA 401 module on a CAN bus; [bus] kind is not \"can\""
                        ),
                    ));
                }
                self.check_module_node(ctx, node, &p.key)?;
                let bit = need_bit(p, 64)?;
                self.check_module_size(node, bit, p)?;
                Ok(Wiring::Module { node, bit })
            }
            (None, Some(drive)) => {
                if !can {
                    return Err(bad(
                        format!("{}.drive", p.key),
                        "a drive's own I/O (0x60FD/0x60FE) is read on a CAN bus only".into(),
                    ));
                }
                let axis = drive_axis(ctx, drive, &p.key)?;
                Ok(Wiring::Drive {
                    axis,
                    bit: need_bit(p, 32)?,
                })
            }
            (None, None) => match ctx.bus {
                BusConfig::Sim { .. } => Ok(Wiring::Sim),
                BusConfig::Serial(_) => Ok(Wiring::Serial {
                    bit: need_bit(p, 64)?,
                }),
                BusConfig::Can(_) => Err(InvalidConfig::Missing {
                    key: format!("{}.node_id", p.key),
                    detail: "on a CAN bus give node_id (a CiA 401 module) or drive".into(),
                }),
            },
        }
    }

    fn check_module_node(&self, ctx: &IoContext, node: u8, key: &str) -> Result<(), InvalidConfig> {
        let key = format!("{key}.node_id");
        if !(1..=127).contains(&node) {
            return Err(bad(key, format!("{node} is outside 1..127")));
        }
        if let Some(a) = ctx.axes.iter().find(|a| a.node_id == Some(node)) {
            return Err(InvalidConfig::Duplicate {
                key,
                detail: format!(
                    "node {node} is the drive of axis {0}; its own inputs are drive = \"{0}\"",
                    a.name
                ),
            });
        }
        if let BusConfig::Can(c) = ctx.bus
            && (c.master_node_id == node || c.spindle_node == Some(node))
        {
            return Err(InvalidConfig::Duplicate {
                key,
                detail: format!("node {node} is the controller's or the spindle drive's"),
            });
        }
        Ok(())
    }

    fn check_module_size(&self, node: u8, bit: u8, p: &PointKeys) -> Result<(), InvalidConfig> {
        let Some(m) = self.modules.iter().find(|m| m.node_id == node) else {
            return Ok(());
        };
        let size = module_bits(m, p.input);
        if bit >= size {
            return Err(bad(
                format!("{}.bit", p.key),
                format!(
                    "bit {bit} is outside module {node}, which has {size} {} (io.modules)",
                    if p.input { "inputs" } else { "outputs" }
                ),
            ));
        }
        Ok(())
    }
}

fn module_bits(m: &ModuleConfig, input: bool) -> u8 {
    if input { m.input_bits } else { m.output_bits }
}

impl<'a> PointKeys<'a> {
    fn of(
        key: &str,
        input: bool,
        node_id: Option<u8>,
        drive: &'a Option<String>,
        bit: Option<u8>,
    ) -> Self {
        PointKeys {
            key: key.to_string(),
            node_id,
            drive: drive.as_deref(),
            bit,
            input,
        }
    }
}

impl InputConfig {
    fn point_keys(&self, key: &str) -> PointKeys<'_> {
        PointKeys::of(key, true, self.node_id, &self.drive, self.bit)
    }
}

impl OutputConfig {
    fn point_keys(&self, key: &str) -> PointKeys<'_> {
        PointKeys::of(key, false, self.node_id, &self.drive, self.bit)
    }
}

fn need_bit(p: &PointKeys, below: u8) -> Result<u8, InvalidConfig> {
    match p.bit {
        None => Err(InvalidConfig::Missing {
            key: format!("{}.bit", p.key),
            detail: "the bit of the point is missing".into(),
        }),
        Some(b) if b >= below => Err(bad(
            format!("{}.bit", p.key),
            format!("bit {b} is outside 0..{}", below - 1),
        )),
        Some(b) => Ok(b),
    }
}

/// The axis index of `drive = "X"` (or the spindle's).
fn drive_axis(ctx: &IoContext, drive: &str, key: &str) -> Result<u8, InvalidConfig> {
    if drive.eq_ignore_ascii_case("spindle") {
        return match ctx.bus {
            BusConfig::Can(c) if c.spindle_node.is_some() => Ok(hal::SPINDLE_AXIS),
            _ => Err(bad(
                format!("{key}.drive"),
                "there is no spindle drive on the bus (bus.spindle_node)".into(),
            )),
        };
    }
    let mut chars = drive.chars();
    let letter = chars.next().filter(|_| chars.next().is_none());
    letter
        .and_then(|l| ctx.axes.iter().position(|a| a.name == l))
        .map(|i| i as u8)
        .ok_or_else(|| {
            bad(
                format!("{key}.drive"),
                format!("'{drive}' is not an axis of this machine (nor \"spindle\")"),
            )
        })
}

/// One input (or output) per point: the second naming it is refused.
fn no_twice(
    seen: &mut Vec<(Wiring, String)>,
    w: Wiring,
    key: &str,
    what: &str,
) -> Result<(), InvalidConfig> {
    if w == Wiring::Sim {
        return Ok(());
    }
    if let Some((_, first)) = seen.iter().find(|(s, _)| *s == w) {
        return Err(InvalidConfig::Duplicate {
            key: key.to_string(),
            detail: format!("the same {what} point as {first}: one {what}, one function"),
        });
    }
    seen.push((w, key.to_string()));
    Ok(())
}

fn check_input(
    inp: &InputConfig,
    w: Wiring,
    ctx: &IoContext,
    key: &str,
) -> Result<(), InvalidConfig> {
    let needs_axis = matches!(
        inp.function,
        InputFunction::LimitNeg | InputFunction::LimitPos | InputFunction::Home
    );
    if needs_axis
        && inp.axis.is_none()
        && !matches!(w, Wiring::Drive { axis, .. } if usize::from(axis) < ctx.axes.len())
    {
        return Err(InvalidConfig::Missing {
            key: format!("{key}.axis"),
            detail: "a limit or home switch names its axis".into(),
        });
    }
    if let Some(a) = inp.axis
        && !ctx.axes.iter().any(|c| c.name == a)
    {
        return Err(bad(
            format!("{key}.axis"),
            format!("'{a}' is not an axis of this machine"),
        ));
    }
    if inp.timeout_ms == 0 {
        return Err(bad(
            format!("{key}.timeout_ms"),
            "must be at least 1 ms".into(),
        ));
    }
    for (j, m) in inp.confirms.iter().enumerate() {
        m_code_free(m, ctx, &format!("{key}.confirms[{j}]"))?;
    }
    Ok(())
}

fn check_output(out: &OutputConfig, ctx: &IoContext, key: &str) -> Result<(), InvalidConfig> {
    if out.safe > 1 {
        return Err(bad(
            format!("{key}.safe"),
            format!("{} must be 0 or 1", out.safe),
        ));
    }
    if out.pulse_ms == Some(0) {
        return Err(bad(
            format!("{key}.pulse_ms"),
            "a pulse lasts at least 1 ms".into(),
        ));
    }
    let mut codes = Vec::new();
    for (list, name) in [(&out.on, "on"), (&out.off, "off")] {
        for (j, m) in list.iter().enumerate() {
            let k = format!("{key}.{name}[{j}]");
            let code = m_code_free(m, ctx, &k)?;
            if codes.contains(&code) {
                return Err(InvalidConfig::Duplicate {
                    key: k,
                    detail: format!("M{code} is given twice for this output"),
                });
            }
            codes.push(code);
        }
    }
    Ok(())
}

/// "M8": a code no built-in function (nor a gear range) uses.
fn m_code_free(m: &str, ctx: &IoContext, key: &str) -> Result<u16, InvalidConfig> {
    let Some(code) = parse_m(m) else {
        return Err(bad(
            key.to_string(),
            format!("'{m}' is not an M function (e.g. \"M8\")"),
        ));
    };
    if RESERVED_M.contains(&code) || ctx.gear_m.contains(&code) {
        return Err(bad(
            key.to_string(),
            format!("M{code} has a meaning of its own in this controller (docs/io.md)"),
        ));
    }
    Ok(code)
}

fn bad(key: String, detail: String) -> InvalidConfig {
    InvalidConfig::BadValue { key, detail }
}
