//! Commands of the Plc service: PLC memory area 1, by cell name or address.

use proto::v1 as pb;
use proto::v1::plc_client::PlcClient;
use serde_json::{Value, json};

use crate::args::PlcCmd;
use crate::call::{Reply, call_as};
use crate::connect::Svc;
use crate::render::Render;

/// Lists, reads or writes cells and prints them.
pub async fn command(p: &mut PlcClient<Svc>, cmd: PlcCmd, j: bool) -> Reply {
    match cmd {
        PlcCmd::List => call_as(j, p.list_cells(pb::ListCellsRequest {}), |r| Cells(r.cells)).await,
        PlcCmd::Read { cells } => {
            let cells = cells.iter().map(|s| cell_ref(s)).collect();
            call_as(j, p.read_cells(pb::ReadCellsRequest { cells }), |r| {
                Cells(r.cells)
            })
            .await
        }
        PlcCmd::Write { cell, value } => {
            let cell = Some(cell_ref(&cell));
            call_as(j, p.write_cell(pb::WriteCellRequest { cell, value }), |c| {
                Cells(vec![c])
            })
            .await
        }
    }
}

/// `0xA19C`, `A19Ch` (an address) or a cell name.
fn cell_ref(s: &str) -> pb::CellRef {
    let hex = s
        .strip_prefix("0x")
        .or_else(|| s.strip_prefix("0X"))
        .or_else(|| s.strip_suffix('h').or_else(|| s.strip_suffix('H')));
    let cell = match hex.and_then(|h| u32::from_str_radix(h, 16).ok()) {
        Some(a) => pb::cell_ref::Cell::Address(a),
        None => pb::cell_ref::Cell::Name(s.to_string()),
    };
    pb::CellRef { cell: Some(cell) }
}

struct Cells(Vec<pb::PlcCell>);

impl Render for Cells {
    fn json(&self) -> Value {
        Value::Array(self.0.iter().map(cell_json).collect())
    }
    fn human(&self) -> String {
        self.0
            .iter()
            .map(|c| {
                let rw = if c.access == pb::CellAccess::ReadOnly as i32 {
                    "R "
                } else {
                    "RW"
                };
                format!(
                    "{:X}h {:<15} {rw} {:>12} {}",
                    c.address, c.name, c.value, c.unit
                )
            })
            .collect::<Vec<_>>()
            .join("\n")
    }
}

fn cell_json(c: &pb::PlcCell) -> Value {
    json!({"name": c.name, "address": format!("{:X}h", c.address), "value": c.value, "unit": c.unit,
        "access": pb::CellAccess::try_from(c.access).map(|a| a.as_str_name()).unwrap_or("?"),
        "min": c.min, "max": c.max, "description": c.description})
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_are_named_or_addressed_in_hex() {
        let cell = |s| cell_ref(s).cell.unwrap();
        assert_eq!(cell("0xA19C"), pb::cell_ref::Cell::Address(0xA19C));
        assert_eq!(cell("A19Ch"), pb::cell_ref::Cell::Address(0xA19C));
        assert_eq!(cell("AKRR_V"), pb::cell_ref::Cell::Name("AKRR_V".into()));
    }
}
