//! The report's tables: a cell rounded for the page and whole in the CSV, written to the
//! page as HTML and kept as CSV.

use super::svg::escape;
use super::Table;
use std::fmt::Write;

/// One entry of a table: on the page a number is rounded for reading; in the CSV it is
/// written whole (shortest exact form), so a script reads what was computed.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Cell {
    /// Words.
    Text(String),
    /// A number and the decimals shown on the page.
    Number(f64, usize),
    /// Nothing (not applicable).
    Empty,
}

impl Cell {
    fn page(&self) -> String {
        match self {
            Cell::Text(t) => t.clone(),
            Cell::Number(v, decimals) => format!("{v:.decimals$}"),
            Cell::Empty => String::new(),
        }
    }

    fn csv(&self) -> String {
        match self {
            Cell::Text(t) => t.clone(),
            Cell::Number(v, _) => format!("{v}"),
            Cell::Empty => String::new(),
        }
    }
}

/// Words in a table.
pub(super) fn text(t: impl Into<String>) -> Cell {
    Cell::Text(t.into())
}

/// A number shown with `decimals` decimals.
pub(super) fn num(v: f64, decimals: usize) -> Cell {
    Cell::Number(v, decimals)
}

/// A count.
pub(super) fn count(v: u64) -> Cell {
    Cell::Number(v as f64, 0)
}

fn html_table(out: &mut String, header: &[String], rows: &[Vec<Cell>]) {
    out.push_str("<table>\n<tr>");
    for h in header {
        let _ = write!(out, "<th>{}</th>", escape(h));
    }
    out.push_str("</tr>\n");
    for r in rows {
        out.push_str("<tr>");
        for c in r {
            let _ = write!(out, "<td>{}</td>", escape(&c.page()));
        }
        out.push_str("</tr>\n");
    }
    out.push_str("</table>\n");
}

/// A table on the page and as `name`.csv.
pub(super) fn add_table(
    page: &mut String,
    tables: &mut Vec<Table>,
    name: &str,
    header: &[String],
    rows: &[Vec<Cell>],
) {
    add_table_with_csv(page, tables, name, header, rows, header, rows);
}

/// A table on the page, and as `name`.csv with its own columns (more than the page shows).
pub(super) fn add_table_with_csv(
    page: &mut String,
    tables: &mut Vec<Table>,
    name: &str,
    header: &[String],
    rows: &[Vec<Cell>],
    csv_header: &[String],
    csv_rows: &[Vec<Cell>],
) {
    html_table(page, header, rows);
    let csv_rows: Vec<Vec<String>> = csv_rows
        .iter()
        .map(|r| r.iter().map(Cell::csv).collect())
        .collect();
    tables.push(Table {
        name: name.into(),
        csv: csv(csv_header, &csv_rows),
    });
}

pub(super) fn csv(header: &[String], rows: &[Vec<String>]) -> String {
    let quote = |s: &String| {
        if s.contains([',', '"', '\n']) {
            format!("\"{}\"", s.replace('"', "\"\""))
        } else {
            s.clone()
        }
    };
    let mut out = header.iter().map(quote).collect::<Vec<_>>().join(",");
    out.push('\n');
    for r in rows {
        out.push_str(&r.iter().map(quote).collect::<Vec<_>>().join(","));
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_quotes_what_needs_quoting() {
        let out = csv(
            &["a".into(), "b".into()],
            &[vec!["x, y".into(), "say \"hi\"".into()]],
        );
        assert_eq!(out, "a,b\n\"x, y\",\"say \"\"hi\"\"\"\n");
    }

    #[test]
    fn numbers_are_rounded_on_the_page_and_whole_in_the_csv() {
        let mut page = String::new();
        let mut tables = Vec::new();
        add_table(
            &mut page,
            &mut tables,
            "t",
            &["p".into(), "n".into(), "note".into()],
            &[vec![num(0.000123456789, 4), count(7), Cell::Empty]],
        );
        assert!(
            page.contains("<td>0.0001</td><td>7</td><td></td>"),
            "{page}"
        );
        assert_eq!(tables[0].csv, "p,n,note\n0.000123456789,7,\n");
    }
}
