//! Services `cnc.v1.Offsets`, `cnc.v1.Plc` and `cnc.v1.Constants`.

use std::sync::Arc;

use proto::v1 as pb;
use proto::v1::constants_server::Constants as ConstantsRpc;
use proto::v1::offsets_server::Offsets;
use proto::v1::plc_server::Plc;
use tonic::{Request, Response, Status};

use kernel::constants::{self, Constants, MAX_R};
use kernel::machine::names;
use kernel::offsets::work::{SYSTEM_NAMES, SYSTEMS};
use kernel::offsets::work_file::WorkEdit;
use kernel::offsets::{self, ENTRIES, OffsetTable, TableEdit, WorkOffsets};
use kernel::plc::{self, Access, CellInfo, PlcWrite};

use super::auth::require;
use super::{ApiState, blocking, diagnostic_to_pb, invalid_with_diagnostics, status_of};
use crate::runtime::config::Role::{Admin, Observer, Operator};

#[derive(Clone)]
pub struct OffsetsSvc(pub Arc<ApiState>);
#[derive(Clone)]
pub struct PlcSvc(pub Arc<ApiState>);
#[derive(Clone)]
pub struct ConstantsSvc(pub Arc<ApiState>);

fn entry_pb(n: u8, memory: &OffsetTable, file: Option<&OffsetTable>) -> pb::OffsetEntry {
    let e = memory.entry(n).copied().unwrap_or_default();
    let changed = file.is_some_and(|f| f.entry(n).copied().unwrap_or_default() != e);
    pb::OffsetEntry {
        entry: n.into(),
        radius_mm: e.radius_mm,
        length_mm: e.length_mm.to_vec(),
        changed_by_program: changed,
    }
}

impl OffsetsSvc {
    /// The work offsets for the API.
    fn work_table(&self) -> pb::WorkOffsetTable {
        let names = self.0.ctl.config().axis_names();
        work_table_pb(
            &self.0.ctl.work_offsets(),
            &names,
            self.0.ctl.work_offsets_file().1,
        )
    }

    /// The file's table (parsed from the text the store would write).
    fn file_table(&self) -> Option<OffsetTable> {
        let names = self.0.ctl.config().axis_names();
        offsets::parse(&self.0.ctl.offsets_file_text(), &names)
            .ok()
            .map(|f| f.table)
    }
}

#[tonic::async_trait]
impl Offsets for OffsetsSvc {
    async fn get_offsets(
        &self,
        req: Request<pb::GetOffsetsRequest>,
    ) -> Result<Response<pb::GetOffsetsReply>, Status> {
        require(&req, Observer, "GetOffsets")?;
        let all = req.into_inner().include_zero;
        let memory = self.0.ctl.offsets_memory();
        let file = self.file_table();
        let names = self.0.ctl.config().axis_names();
        let entries = (1..=ENTRIES)
            .map(|n| entry_pb(n, &memory, file.as_ref()))
            .filter(|e| {
                all || e.changed_by_program
                    || e.radius_mm != 0.0
                    || e.length_mm.iter().any(|v| *v != 0.0)
            })
            .collect();
        Ok(Response::new(pb::GetOffsetsReply {
            entries,
            labels: std::iter::once("R".to_string())
                .chain((1..=4).map(|k| offsets::label(k, &names)))
                .collect(),
            work_offsets: Some(self.work_table()),
        }))
    }

    async fn list_work_offsets(
        &self,
        req: Request<pb::ListWorkOffsetsRequest>,
    ) -> Result<Response<pb::WorkOffsetTable>, Status> {
        require(&req, Observer, "ListWorkOffsets")?;
        // A hand edit saved since the last look is shown (and loaded) at once.
        let st = self.0.clone();
        blocking(move || st.ctl.sync_files()).await?;
        Ok(Response::new(self.work_table()))
    }

    async fn set_work_offset(
        &self,
        req: Request<pb::SetWorkOffsetRequest>,
    ) -> Result<Response<pb::WorkOffsetTable>, Status> {
        require(&req, Operator, "SetWorkOffset")?;
        let edit = work_edit(&req.into_inner(), &self.0.ctl.config().axis_names())?;
        let st = self.0.clone();
        blocking(move || st.ctl.edit_work_offset(&edit))
            .await?
            .map_err(status_of)?;
        Ok(Response::new(self.work_table()))
    }

    async fn touch_off(
        &self,
        req: Request<pb::TouchOffRequest>,
    ) -> Result<Response<pb::TouchOffReply>, Status> {
        require(&req, Operator, "TouchOff")?;
        super::diagnostics::ready_for_motion(self.0.ctl.snapshot().state)?;
        let reply = super::touch_off::touch_off(self.0.clone(), req.into_inner()).await?;
        Ok(Response::new(reply))
    }

    async fn probe_workflow(
        &self,
        req: Request<pb::ProbeWorkflowRequest>,
    ) -> Result<Response<pb::ProbeWorkflowReply>, Status> {
        require(&req, Operator, "ProbeWorkflow")?;
        super::diagnostics::ready_for_motion(self.0.ctl.snapshot().state)?;
        let reply = super::probe::workflow(self.0.clone(), req.into_inner()).await?;
        Ok(Response::new(reply))
    }

    async fn set_offset(
        &self,
        req: Request<pb::SetOffsetRequest>,
    ) -> Result<Response<pb::OffsetEntry>, Status> {
        require(&req, Operator, "SetOffset")?;
        let r = req.into_inner();
        let entry = u8::try_from(r.entry)
            .ok()
            .filter(|n| (1..=ENTRIES).contains(n))
            .ok_or_else(|| {
                Status::invalid_argument(format!(
                    "offset entry {} does not exist: entries are 01..99",
                    r.entry
                ))
            })?;
        let edit = TableEdit {
            entry,
            values: [
                r.radius_mm,
                r.length1_mm,
                r.length2_mm,
                r.length3_mm,
                r.length4_mm,
            ],
        };
        if edit.values.iter().all(Option::is_none) {
            return Err(Status::invalid_argument(
                "give at least one value (radius_mm, length1_mm..length4_mm)",
            ));
        }
        let names = self.0.ctl.config().axis_names();
        for (k, v) in edit.values.iter().enumerate() {
            if let Some(v) = v {
                let field = if k == 0 {
                    format!("D{entry:02} radius (R)")
                } else {
                    format!("D{entry:02} length {}", offsets::label(k, &names))
                };
                check_value(
                    &field,
                    *v,
                    offsets::MAX_VALUE_MM,
                    offsets::MAX_DECIMALS as u32,
                )?;
            }
        }
        let st = self.0.clone();
        blocking(move || st.ctl.edit_offset(&edit))
            .await?
            .map_err(status_of)?;
        let memory = self.0.ctl.offsets_memory();
        let file = self.file_table();
        Ok(Response::new(entry_pb(entry, &memory, file.as_ref())))
    }

    async fn get_offsets_file(
        &self,
        req: Request<pb::GetOffsetsFileRequest>,
    ) -> Result<Response<pb::OffsetsFile>, Status> {
        require(&req, Observer, "GetOffsetsFile")?;
        // A hand edit saved since the last look is shown (and loaded) at once.
        let st = self.0.clone();
        blocking(move || st.ctl.sync_files()).await?;
        Ok(Response::new(pb::OffsetsFile {
            text: self.0.ctl.offsets_file_text(),
            revision: self.0.ctl.offsets_revision(),
        }))
    }

    async fn replace_offsets_file(
        &self,
        req: Request<pb::OffsetsFile>,
    ) -> Result<Response<pb::ReplaceOffsetsFileReply>, Status> {
        require(&req, Operator, "ReplaceOffsetsFile")?;
        let pb::OffsetsFile { text, revision } = req.into_inner();
        let base = (!revision.is_empty()).then_some(revision);
        let st = self.0.clone();
        blocking(move || st.ctl.replace_offsets_file(&text, base.as_deref()))
            .await?
            .map_err(status_of)?;
        Ok(Response::new(pb::ReplaceOffsetsFileReply {
            entries: self.0.ctl.offsets_memory().iter_nonzero().count() as u32,
        }))
    }

    async fn reload_offsets(
        &self,
        req: Request<pb::ReloadOffsetsRequest>,
    ) -> Result<Response<pb::ReloadOffsetsReply>, Status> {
        require(&req, Operator, "ReloadOffsets")?;
        let st = self.0.clone();
        blocking(move || st.ctl.reload_offsets())
            .await?
            .map_err(status_of)?;
        Ok(Response::new(pb::ReloadOffsetsReply {
            entries: self.0.ctl.offsets_memory().iter_nonzero().count() as u32,
        }))
    }
}

/// The nine systems (G54 first), each with a value per axis of `names`.
fn work_table_pb(w: &WorkOffsets, names: &[char], revision: String) -> pb::WorkOffsetTable {
    let axes = names.len().min(kernel::MAX_AXES);
    pb::WorkOffsetTable {
        axes: names.iter().map(char::to_string).collect(),
        systems: (0..SYSTEMS)
            .map(|k| pb::WorkOffsetSystem {
                name: SYSTEM_NAMES[k].into(),
                offset_mm: w.systems[k].0[..axes].to_vec(),
            })
            .collect(),
        active_at_start: SYSTEM_NAMES[w.active].into(),
        revision,
    }
}

/// A `SetWorkOffset` request as an edit: a known system, known axes once each, values the
/// file keeps exactly (INVALID_ARGUMENT otherwise, naming the value).
fn work_edit(r: &pb::SetWorkOffsetRequest, names: &[char]) -> Result<WorkEdit, Status> {
    let system = WorkOffsets::index_of(&r.system).ok_or_else(|| {
        Status::invalid_argument(format!(
            "work offset system {:?} does not exist: G54 .. G59, G59.1 .. G59.3",
            r.system
        ))
    })?;
    if r.values.is_empty() {
        return Err(Status::invalid_argument("give at least one axis value"));
    }
    let mut values = [None; kernel::MAX_AXES];
    for v in &r.values {
        let axis = names
            .iter()
            .position(|n| v.axis.trim().eq_ignore_ascii_case(&n.to_string()))
            .ok_or_else(|| {
                Status::invalid_argument(format!("this machine has no axis {:?}", v.axis))
            })?;
        if values[axis].is_some() {
            return Err(Status::invalid_argument(format!(
                "axis {} is given twice",
                names[axis]
            )));
        }
        let field = format!("{} {}", SYSTEM_NAMES[system], names[axis]);
        check_value(
            &field,
            v.value_mm,
            offsets::MAX_VALUE_MM,
            offsets::MAX_DECIMALS as u32,
        )?;
        values[axis] = Some(v.value_mm);
    }
    Ok(WorkEdit { system, values })
}

fn cell_pb(info: &CellInfo, value: i32) -> pb::PlcCell {
    pb::PlcCell {
        name: info.name.into(),
        address: info.address,
        value: value.into(),
        unit: info.unit.symbol().into(),
        access: match info.access {
            Access::ReadOnly => pb::CellAccess::ReadOnly,
            Access::ReadWrite => pb::CellAccess::ReadWrite,
        } as i32,
        min: info.min.into(),
        max: info.max.into(),
        description: info.description.into(),
    }
}

fn find_cell(r: &pb::CellRef) -> Result<&'static CellInfo, Status> {
    use pb::cell_ref::Cell;
    match &r.cell {
        Some(Cell::Name(n)) => plc::by_name(n).ok_or_else(|| {
            Status::invalid_argument(format!(
                "there is no PLC cell named \"{n}\" in memory area 1"
            ))
        }),
        Some(Cell::Address(a)) => plc::by_address(*a).ok_or_else(|| {
            Status::invalid_argument(format!(
                "there is no PLC cell at address {a:X}h in memory area 1"
            ))
        }),
        None => Err(Status::invalid_argument("name the cell by name or address")),
    }
}

#[tonic::async_trait]
impl Plc for PlcSvc {
    async fn list_cells(
        &self,
        req: Request<pb::ListCellsRequest>,
    ) -> Result<Response<pb::CellsReply>, Status> {
        require(&req, Observer, "ListCells")?;
        let area = self.0.ctl.snapshot().plc;
        Ok(Response::new(pb::CellsReply {
            cells: area.list().map(|(i, v)| cell_pb(i, v)).collect(),
        }))
    }

    async fn read_cells(
        &self,
        req: Request<pb::ReadCellsRequest>,
    ) -> Result<Response<pb::CellsReply>, Status> {
        require(&req, Observer, "ReadCells")?;
        let area = self.0.ctl.snapshot().plc;
        let cells = req
            .into_inner()
            .cells
            .iter()
            .map(|r| find_cell(r).map(|i| cell_pb(i, area.latest(i.id))))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Response::new(pb::CellsReply { cells }))
    }

    async fn write_cell(
        &self,
        req: Request<pb::WriteCellRequest>,
    ) -> Result<Response<pb::PlcCell>, Status> {
        require(&req, Operator, "WriteCell")?;
        let r = req.into_inner();
        let info = find_cell(r.cell.as_ref().unwrap_or(&pb::CellRef { cell: None }))?;
        let w = PlcWrite::new(info.address, r.value)
            .map_err(|e| Status::invalid_argument(e.to_string()))?;
        self.0.ctl.plc_write(w).map_err(status_of)?;
        // Read-your-write: reply once the RT thread has taken the write (next tick), so a
        // ReadCells right after this call sees the value.
        let t0 = std::time::Instant::now();
        while self.0.ctl.snapshot().plc.latest(info.id) != w.value()
            && t0.elapsed() < std::time::Duration::from_millis(200)
        {
            tokio::time::sleep(std::time::Duration::from_millis(1)).await;
        }
        Ok(Response::new(cell_pb(info, w.value())))
    }
}

/// A value given over the API: within ±`max` and with at most `decimals` decimals. Values
/// that would need rounding are refused with the precision allowed, never rounded silently
/// (the file keeps `decimals`; memory must hold what the file holds). The refusal names the
/// field (`R52`, `D06 radius (R)`) in its message and in a `Diagnostics` detail.
fn check_value(field: &str, v: f64, max: f64, decimals: u32) -> Result<(), Status> {
    let refuse = |code: kernel::DiagCode, m: String| {
        let d = kernel::Diagnostic::error(code, None, 0, 0, m);
        invalid_with_diagnostics(field, std::slice::from_ref(&d))
    };
    if !(v.is_finite() && v.abs() <= max) {
        return Err(refuse(
            kernel::DiagCode::ValueOutOfRange,
            format!("{field} = {v} is outside ±{max}"),
        ));
    }
    let d = decimals as usize;
    let kept: f64 = format!("{v:.d$}").parse().unwrap_or(f64::NAN);
    if kept != v {
        let step = 10f64.powi(-(decimals as i32));
        let lo = (v / step).floor() * step;
        return Err(refuse(
            kernel::DiagCode::ValueTooPrecise,
            format!(
                "{field} = {v} has more than {decimals} decimals: the value is kept to {step:.d$}; \
             write {lo:.d$} or {:.d$}",
                lo + step
            ),
        ));
    }
    Ok(())
}

fn constant_pb(c: &Constants, r: u16) -> pb::Constant {
    let is_default = !c.iter().any(|(n, _)| n == r);
    let named = names::constant_name(r);
    pb::Constant {
        name: named.map(|k| k.name.into()).unwrap_or_default(),
        unit: named.map(|k| k.unit.into()).unwrap_or_default(),
        meaning: named.map(|k| k.meaning.into()).unwrap_or_default(),
        number: r.into(),
        value: c.get(r),
        text: constants::fmt_milli(c.milli(r)),
        decades: (1..=8).map(|d| c.decade(r, d).into()).collect(),
        negative: c.is_negative(r),
        is_default,
    }
}

#[tonic::async_trait]
impl ConstantsRpc for ConstantsSvc {
    async fn get_constants(
        &self,
        req: Request<pb::GetConstantsRequest>,
    ) -> Result<Response<pb::GetConstantsReply>, Status> {
        require(&req, Observer, "GetConstants")?;
        let numbers = req.into_inner().numbers;
        let c = self.0.ctl.constants();
        let list: Vec<u16> = if numbers.is_empty() {
            (0..=MAX_R)
                .filter(|&r| {
                    // Every constant the controller reads too: a screen names them all, set
                    // or not (R384 is 0, off, until a constants file sets it).
                    constants::default_of(r) != 0
                        || names::constant_name(r).is_some()
                        || c.iter().any(|(n, _)| n == r)
                })
                .collect()
        } else {
            numbers
                .iter()
                .map(|&n| {
                    u16::try_from(n)
                        .ok()
                        .filter(|&r| r <= MAX_R)
                        .ok_or_else(|| {
                            Status::invalid_argument(format!(
                                "R{n} does not exist: constants are R0..R{MAX_R}"
                            ))
                        })
                })
                .collect::<Result<_, _>>()?
        };
        Ok(Response::new(pb::GetConstantsReply {
            constants: list.iter().map(|&r| constant_pb(&c, r)).collect(),
        }))
    }

    async fn set_constants(
        &self,
        req: Request<pb::SetConstantsRequest>,
    ) -> Result<Response<pb::SetConstantsReply>, Status> {
        require(&req, Admin, "SetConstants")?;
        let values = req.into_inner().values;
        if values.is_empty() {
            return Err(Status::invalid_argument("give at least one constant"));
        }
        let mut parsed = Vec::with_capacity(values.len());
        for v in &values {
            let r = u16::try_from(v.number)
                .ok()
                .filter(|&r| r <= MAX_R)
                .ok_or_else(|| {
                    Status::invalid_argument(format!(
                        "R{} does not exist: constants are R0..R{MAX_R}",
                        v.number
                    ))
                })?;
            check_value(&format!("R{r}"), v.value, 99_999.999, 3)?;
            parsed.push((r, v.value));
        }
        // Check the combination before anything is saved: all or nothing.
        let mut next = self.0.ctl.constants();
        for &(r, v) in &parsed {
            next.set(r, v);
        }
        let diags = next.validate();
        if diags.iter().any(|d| d.is_error()) {
            return Err(invalid_with_diagnostics("constants", &diags));
        }
        let st = self.0.clone();
        let p = parsed.clone();
        let restart = blocking(move || st.ctl.set_constants(&p))
            .await?
            .map_err(status_of)?;
        Ok(Response::new(pb::SetConstantsReply {
            restart_required: restart.into_iter().map(u32::from).collect(),
            diagnostics: diags.iter().map(diagnostic_to_pb).collect(),
        }))
    }
}
