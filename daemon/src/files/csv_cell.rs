//! Spreadsheet formulas in CSV text cells, neutralised as OWASP recommends.
//!
//! A plant id, note or path that starts with `=`, `+`, `-`, `@`, a tab or a
//! carriage return is run as a formula when a person opens the CSV in a
//! spreadsheet (`=HYPERLINK(…)`, `@SUM(…)`). Every CSV phyllo writes for
//! people therefore prefixes such a cell with `'`, which spreadsheets show as
//! text; numbers (`-1.5`, `+3`) stay as they are. phyllo's imports take the
//! prefix off again, so a sheet read back holds what was written.

use std::borrow::Cow;

/// Whether a spreadsheet could read `cell` as a formula.
fn starts_like_a_formula(cell: &str) -> bool {
    cell.starts_with(['=', '+', '-', '@', '\t', '\r'])
}

/// `cell` as written to a CSV: `'` before text a spreadsheet would run.
pub fn neutralise(cell: &str) -> Cow<'_, str> {
    if starts_like_a_formula(cell) && cell.trim().parse::<f64>().is_err() {
        Cow::Owned(format!("'{cell}"))
    } else {
        Cow::Borrowed(cell)
    }
}

/// A cell read back from a CSV: [`neutralise`]'s `'` taken off again.
pub fn restore(cell: &str) -> &str {
    match cell.strip_prefix('\'') {
        Some(rest) if starts_like_a_formula(rest) && rest.trim().parse::<f64>().is_err() => rest,
        _ => cell,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formulas_are_neutralised_and_numbers_kept() {
        for (cell, written) in [
            (
                "=HYPERLINK(\"http://x\",\"y\")",
                "'=HYPERLINK(\"http://x\",\"y\")",
            ),
            ("@SUM(A1:A2)", "'@SUM(A1:A2)"),
            ("+cmd|' /C calc'!A0", "'+cmd|' /C calc'!A0"),
            ("-2+3", "'-2+3"),
            ("\tx", "'\tx"),
            ("\rx", "'\rx"),
            ("-1.5", "-1.5"),
            ("+3", "+3"),
            ("-0", "-0"),
            ("81-265-CML332", "81-265-CML332"),
            ("", ""),
            ("'quoted", "'quoted"),
        ] {
            assert_eq!(neutralise(cell), written, "{cell:?}");
            assert_eq!(restore(&neutralise(cell)), cell, "{cell:?} reads back");
        }
    }
}
