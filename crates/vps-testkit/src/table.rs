//! The CSV tables the `vps` binary writes (a study's `path.csv`, `pair_clearance.csv`) read back
//! as numbers by column name.

/// The header and the rows of CSV `text` as numbers (`true`/`false` as 1/0, an empty cell NaN).
/// Panics on a cell that is none of these.
pub fn csv_table(text: &str) -> (Vec<String>, Vec<Vec<f64>>) {
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .expect("a header line")
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| {
            l.split(',')
                .map(|c| match c {
                    "true" => 1.0,
                    "false" => 0.0,
                    "" => f64::NAN,
                    x => x.parse().unwrap_or_else(|_| panic!("not a number: {x:?}")),
                })
                .collect()
        })
        .collect();
    (header, rows)
}

/// Column `name` of CSV `text` ([`csv_table`]). Panics, naming the header, when there is none.
pub fn csv_column(text: &str, name: &str) -> Vec<f64> {
    let (header, rows) = csv_table(text);
    let k = header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name} in {header:?}"));
    rows.iter().map(|r| r[k]).collect()
}
