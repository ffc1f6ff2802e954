//! Commands of the Constants service: machine constants (R numbers), decades decoded.

use proto::v1 as pb;
use proto::v1::constants_client::ConstantsClient;
use serde_json::{Value, json};

use crate::args::ConstCmd;
use crate::call::{Reply, call};
use crate::connect::Svc;
use crate::error::CliError;
use crate::render::{Render, diag_lines, diags_json};

/// Reads or sets constants and prints the answer.
pub async fn command(k: &mut ConstantsClient<Svc>, cmd: ConstCmd, j: bool) -> Reply {
    match cmd {
        ConstCmd::Get { numbers } => {
            let numbers = numbers
                .iter()
                .map(|n| constant_number(n))
                .collect::<Result<Vec<_>, _>>()?;
            call(j, k.get_constants(pb::GetConstantsRequest { numbers })).await
        }
        ConstCmd::Set { values } => {
            let values = values
                .iter()
                .map(|v| parse_assignment(v))
                .collect::<Result<Vec<_>, _>>()?;
            call(j, k.set_constants(pb::SetConstantsRequest { values })).await
        }
    }
}

/// `R384` or `384` → 384 (issue #31: both spellings, as in `constants set`).
fn constant_number(n: &str) -> Result<u32, CliError> {
    n.strip_prefix(['R', 'r'])
        .unwrap_or(n)
        .parse()
        .map_err(|_| CliError::ConstantNumber(n.to_string()))
}

/// `R39=45` (or `39=45`) → constant 39, value 45.
fn parse_assignment(v: &str) -> Result<pb::ConstantValue, CliError> {
    let (r, x) = v
        .trim_start_matches(['R', 'r'])
        .split_once('=')
        .ok_or_else(|| CliError::ConstantSyntax(v.to_string()))?;
    Ok(pb::ConstantValue {
        number: r
            .parse()
            .map_err(|_| CliError::ConstantNumber(v.to_string()))?,
        value: x
            .parse()
            .map_err(|_| CliError::ConstantValue(v.to_string()))?,
    })
}

/// The constants with their decades d8..d1 (defaults marked).
impl Render for pb::GetConstantsReply {
    fn json(&self) -> Value {
        Value::Array(self.constants.iter().map(|k| json!({"number": k.number, "value": k.value, "text": k.text, "decades": k.decades, "negative": k.negative, "is_default": k.is_default})).collect())
    }
    fn human(&self) -> String {
        let mut s = "R      value        d8 d7 d6 d5 d4 d3 d2 d1".to_string();
        for k in &self.constants {
            let d: Vec<String> = k.decades.iter().rev().map(|d| format!("{d:>2}")).collect();
            s.push_str(&format!(
                "\nR{:<4} {:>12} {}{}",
                k.number,
                k.text,
                d.join(" "),
                if k.is_default { "  (default)" } else { "" }
            ));
        }
        s
    }
}

/// Saved; which constants need a restart, and any warnings.
impl Render for pb::SetConstantsReply {
    fn json(&self) -> Value {
        json!({"restart_required": self.restart_required, "diagnostics": diags_json(&self.diagnostics)})
    }
    fn human(&self) -> String {
        let mut s = "constants saved; in force from the next program start".to_string();
        if !self.restart_required.is_empty() {
            let numbers: Vec<String> = self
                .restart_required
                .iter()
                .map(|n| format!("R{n}"))
                .collect();
            s.push_str(&format!("\nrestart cncd for: {}", numbers.join(" ")));
        }
        s + &diag_lines(&self.diagnostics)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_parse_with_or_without_r() {
        assert_eq!(constant_number("R384").unwrap(), 384);
        assert_eq!(constant_number("384").unwrap(), 384);
        assert_eq!(constant_number("r7").unwrap(), 7);
        assert_eq!(
            constant_number("Rx").unwrap_err().code(),
            "cli_constant_number"
        );
    }

    #[test]
    fn assignments_parse_with_or_without_r() {
        let v = parse_assignment("R39=45.5").unwrap();
        assert_eq!((v.number, v.value), (39, 45.5));
        assert_eq!(
            parse_assignment("R39=x").unwrap_err().code(),
            "cli_constant_value"
        );
        assert_eq!(parse_assignment("r52=1").unwrap().number, 52);
        assert_eq!(
            parse_assignment("R39").unwrap_err().code(),
            "cli_constant_syntax"
        );
        assert_eq!(
            parse_assignment("Rx=1").unwrap_err().code(),
            "cli_constant_number"
        );
    }
}
