//! Axis scales: "nice" tick steps (1, 2, 5 × 10ⁿ) and their labels.

/// Tick step of about `span / target` rounded to 1, 2 or 5 × 10ⁿ.
pub fn nice_step(span: f64, target: usize) -> f64 {
    if !span.is_finite() || span <= 0.0 {
        return 1.0;
    }
    let raw = span / target.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    let k = if f <= 1.0 {
        1.0
    } else if f <= 2.0 {
        2.0
    } else if f <= 5.0 {
        5.0
    } else {
        10.0
    };
    k * mag
}

/// Ticks (multiples of `step`) within `lo..=hi`.
pub fn ticks(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let mut out = Vec::new();
    if !step.is_finite() || step <= 0.0 || !lo.is_finite() || !hi.is_finite() {
        return out;
    }
    let mut k = (lo / step).ceil();
    while k * step <= hi + step * 1e-9 && out.len() < 1000 {
        // `+ 0.0` turns -0 into 0 for the label.
        out.push(k * step + 0.0);
        k += 1.0;
    }
    out
}

/// Label of a tick: as many decimals as the step needs.
pub fn label(v: f64, step: f64) -> String {
    let decimals = if step >= 1.0 {
        0
    } else {
        (-step.log10().floor()) as usize
    };
    let s = format!("{v:.decimals$}");
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_owned()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_and_labels() {
        assert_eq!(nice_step(100.0, 10), 10.0);
        assert_eq!(nice_step(130.0, 10), 20.0);
        assert_eq!(nice_step(0.3, 10), 0.05);
        assert_eq!(ticks(-1.0, 25.0, 10.0), vec![0.0, 10.0, 20.0]);
        assert_eq!(label(0.05, 0.05), "0.05");
        assert_eq!(label(20.0, 10.0), "20");
        assert_eq!(label(-0.0001, 0.1), "0.0");
    }
}
