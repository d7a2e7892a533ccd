//! Siconos fc2d problem files (`frictionContact_printInFile` layout): the dimension (2), the number
//! of contacts, `W` as a NumericsMatrix (tag 0: dense, column-major; tag 2: a CSparse dump), then
//! `q` (2 per contact) and `μ` (1 per contact). Both storages are read and written, so any problem
//! moreau builds can be handed to Siconos.

use crate::problem::{BlockSparse, ContactProblem, Delassus};
use std::fmt::Write as _;
use std::path::Path;
use thiserror::Error;

/// A problem file that cannot be read or written.
#[derive(Debug, Error)]
pub enum FileError {
    /// The file could not be read or written.
    #[error("{path}: {cause}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        cause: std::io::Error,
    },
    /// A line that cannot be read.
    #[error("{path}: line {line}: {msg}")]
    Parse {
        /// The file.
        path: String,
        /// Line (from 1).
        line: usize,
        /// What is wrong.
        msg: String,
    },
    /// Values that are read but refused.
    #[error("{path}: {msg}")]
    Invalid {
        /// The file.
        path: String,
        /// What is wrong.
        msg: String,
    },
}

#[derive(Debug)]
struct ParseError {
    line: usize,
    msg: String,
}

fn err<T>(line: usize, msg: impl Into<String>) -> Result<T, ParseError> {
    Err(ParseError { line, msg: msg.into() })
}

/// Numbers read line by line, remembering where each came from.
struct Cursor<'a> {
    lines: Vec<&'a str>,
    line: usize,
    tokens: std::vec::IntoIter<&'a str>,
}

impl<'a> Cursor<'a> {
    fn new(text: &'a str) -> Self {
        Self { lines: text.lines().collect(), line: 0, tokens: Vec::new().into_iter() }
    }

    /// 1-based number of the line the last token came from.
    fn line_no(&self) -> usize {
        self.line.max(1)
    }

    fn token(&mut self, what: &str) -> Result<&'a str, ParseError> {
        loop {
            if let Some(t) = self.tokens.next() {
                return Ok(t);
            }
            if self.line >= self.lines.len() {
                return err(self.lines.len(), format!("unexpected end of file while reading {what}"));
            }
            self.tokens = self.lines[self.line].split_whitespace().collect::<Vec<_>>().into_iter();
            self.line += 1;
        }
    }

    fn usize(&mut self, what: &str) -> Result<usize, ParseError> {
        let t = self.token(what)?;
        t.parse().or_else(|_| err(self.line_no(), format!("{what}: expected a non-negative integer, found '{t}'")))
    }

    fn f64(&mut self, what: &str) -> Result<f64, ParseError> {
        let t = self.token(what)?;
        match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => err(self.line_no(), format!("{what}: '{t}' is not a finite number")),
            Err(_) => err(self.line_no(), format!("{what}: expected a number, found '{t}'")),
        }
    }

    /// The next whole line (the current line must be fully consumed).
    fn raw_line(&mut self, what: &str) -> Result<&'a str, ParseError> {
        if self.tokens.len() != 0 {
            return err(self.line_no(), format!("unexpected data before {what}"));
        }
        if self.line >= self.lines.len() {
            return err(self.lines.len(), format!("unexpected end of file while reading {what}"));
        }
        self.line += 1;
        Ok(self.lines[self.line - 1])
    }

    fn peek_line(&self) -> Option<&'a str> {
        if self.tokens.len() != 0 {
            return None;
        }
        self.lines.get(self.line).copied()
    }
}

/// Reads a problem file; errors name the file, the line and the problem.
pub fn read_fc2d(path: &Path) -> Result<ContactProblem, FileError> {
    let p = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|cause| FileError::Io { path: p.clone(), cause })?;
    parse_fc2d(&text).map_err(|e| match e {
        Ok(ParseError { line, msg }) => FileError::Parse { path: p, line, msg },
        Err(msg) => FileError::Invalid { path: p, msg },
    })
}

/// Parses the text of a problem file. `Err(Ok(_))`: a syntax error at a line; `Err(Err(_))`: the
/// content is well-formed but not a valid problem.
fn parse_fc2d(text: &str) -> Result<ContactProblem, Result<ParseError, String>> {
    let mut c = Cursor::new(text);
    let dim = c.usize("dimension").map_err(Ok)?;
    if dim != 2 {
        return Err(Ok(ParseError {
            line: c.line_no(),
            msg: format!("dimension is {dim}: only 2D problems are supported"),
        }));
    }
    let nc = c.usize("number of contacts").map_err(Ok)?;
    if nc > 100_000_000 {
        return Err(Ok(ParseError { line: c.line_no(), msg: format!("number of contacts {nc} is implausibly large") }));
    }
    let w = read_matrix(&mut c, nc).map_err(Ok)?;
    let q = (0..2 * nc).map(|i| c.f64(&format!("q[{i}]"))).collect::<Result<Vec<_>, _>>().map_err(Ok)?;
    let mu = (0..nc).map(|i| c.f64(&format!("mu[{i}]"))).collect::<Result<Vec<_>, _>>().map_err(Ok)?;
    if let Some((a, m)) = mu.iter().enumerate().find(|(_, m)| **m < 0.0) {
        return Err(Err(format!("mu[{a}] = {m} is negative")));
    }
    if let Ok(t) = c.token("end of file") {
        return Err(Ok(ParseError { line: c.line_no(), msg: format!("unexpected trailing data '{t}' after mu") }));
    }
    ContactProblem::new(Delassus::Sparse(w), q, mu).map_err(|e| Err(e.to_string()))
}

fn read_matrix(c: &mut Cursor, nc: usize) -> Result<BlockSparse, ParseError> {
    let n = 2 * nc;
    let tag = c.usize("matrix storage tag")?;
    let (rows, cols) = (c.usize("matrix rows")?, c.usize("matrix columns")?);
    if rows != n || cols != n {
        return err(c.line_no(), format!("W is {rows}×{cols}, expected {n}×{n} for {nc} contacts"));
    }
    match tag {
        0 => {
            let (r2, c2) = (c.usize("dense rows")?, c.usize("dense columns")?);
            if (r2, c2) != (n, n) {
                return err(c.line_no(), format!("dense block is {r2}×{c2}, expected {n}×{n}"));
            }
            let mut entries = Vec::new();
            for j in 0..n {
                for i in 0..n {
                    let v = c.f64(&format!("W[{i},{j}]"))?;
                    if v != 0.0 {
                        entries.push((i, j, v));
                    }
                }
            }
            Ok(BlockSparse::from_scalar_entries(nc, entries))
        }
        2 => read_csparse(c, nc),
        1 => err(c.line_no(), "sparse-block (tag 1) storage is not supported; write W dense (0) or sparse (2)"),
        t => err(c.line_no(), format!("unknown matrix storage tag {t} (0 dense, 2 sparse)")),
    }
}

/// The CSparse `cs_print` dump: `col j : locations a to b` then `i : value` lines.
fn read_csparse(c: &mut Cursor, nc: usize) -> Result<BlockSparse, ParseError> {
    let n = 2 * nc;
    let _origin = c.usize("sparse storage kind")?;
    let banner = c.raw_line("the CSparse banner")?;
    if !banner.trim_start().starts_with("CSparse") {
        return err(c.line_no(), format!("expected the CSparse banner, found '{}'", banner.trim()));
    }
    let header = c.raw_line("the CSparse size line")?;
    let dims = header.split(',').next().unwrap_or("");
    if dims.trim() != format!("{n}-by-{n}") {
        return err(c.line_no(), format!("CSparse size line '{}' does not match {n}-by-{n}", header.trim()));
    }
    let mut entries = Vec::new();
    let mut expected_col = 0usize;
    while let Some(line) = c.peek_line() {
        let t = line.trim();
        if !t.starts_with("col") {
            if t == "..." {
                return err(c.line_no() + 1, "the CSparse dump is truncated ('...'): write it in full");
            }
            break;
        }
        c.raw_line("a column header")?;
        let ln = c.line_no();
        let parts: Vec<&str> = t.split_whitespace().collect();
        // col j : locations a to b
        let parsed = (|| {
            if parts.len() != 7 || parts[2] != ":" || parts[3] != "locations" || parts[5] != "to" {
                return None;
            }
            Some((parts[1].parse::<usize>().ok()?, parts[4].parse::<i64>().ok()?, parts[6].parse::<i64>().ok()?))
        })();
        let Some((j, a, b)) = parsed else {
            return err(ln, format!("malformed column header '{t}'"));
        };
        if j != expected_col || j >= n {
            return err(ln, format!("column {j} out of order or out of range (expected {expected_col})"));
        }
        expected_col += 1;
        for _ in 0..(b - a + 1).max(0) {
            let line = c.raw_line("a matrix entry")?;
            let ln = c.line_no();
            let mut it = line.split(':');
            let (Some(i), Some(v), None) = (it.next(), it.next(), it.next()) else {
                return err(ln, format!("malformed entry '{}' (expected 'row : value')", line.trim()));
            };
            let i: usize = i.trim().parse().or_else(|_| err(ln, format!("bad row index '{}'", i.trim())))?;
            let v: f64 = v.trim().parse().or_else(|_| err(ln, format!("bad value '{}'", v.trim())))?;
            if i >= n {
                return err(ln, format!("row index {i} out of range (W is {n}×{n})"));
            }
            if !v.is_finite() {
                return err(ln, format!("W[{i},{j}] = {v} is not finite"));
            }
            entries.push((i, j, v));
        }
    }
    if expected_col != n {
        return err(c.line_no(), format!("CSparse dump has {expected_col} columns, expected {n}"));
    }
    Ok(BlockSparse::from_scalar_entries(nc, entries))
}

/// Storage of `W` in a written file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Storage {
    /// Every entry of `W`.
    Dense,
    /// Siconos' sparse (CSparse) dump.
    Sparse,
}

/// Writes a problem (assembling `W` if it is matrix-free), full f64 precision. A problem with
/// rolling unknowns is refused: the format has 2 unknowns per contact.
pub fn write_fc2d(problem: &ContactProblem, storage: Storage, path: &Path) -> Result<(), FileError> {
    if problem.has_rolling() {
        let msg = "a problem with rolling resistance has 3 unknowns per contact; the fc2d format holds 2".into();
        return Err(FileError::Invalid { path: path.display().to_string(), msg });
    }
    let text = format_fc2d(problem, storage);
    std::fs::write(path, text).map_err(|cause| FileError::Io { path: path.display().to_string(), cause })
}

/// The fc2d text of `problem` (what [`write_fc2d`] writes).
pub fn format_fc2d(problem: &ContactProblem, storage: Storage) -> String {
    let nc = problem.n_contacts();
    let n = 2 * nc;
    let w = problem.w.to_block_sparse();
    let entries = w.scalar_entries_by_column();
    let mut s = String::new();
    let _ = writeln!(s, "2\n{nc}");
    match storage {
        Storage::Dense => {
            let _ = writeln!(s, "0\n{n}\n{n}\n{n}\t{n}");
            let mut dense = vec![0.0; n * n];
            for &(i, j, v) in &entries {
                dense[j * n + i] = v;
            }
            for col in dense.chunks(n.max(1)) {
                for v in col {
                    let _ = write!(s, " {v:.17e} ");
                }
                s.push('\n');
            }
        }
        Storage::Sparse => {
            let mut col_norm = vec![0.0f64; n];
            for &(_, j, v) in &entries {
                col_norm[j] += v.abs();
            }
            let one_norm = col_norm.iter().cloned().fold(0.0, f64::max);
            let _ = writeln!(s, "2\n{n}\n{n}\n2");
            let _ = writeln!(s, "CSparse Version 3.1.9, May 4, 2016.  Copyright (c) Timothy A. Davis, 2006-2016");
            let nnz = entries.len();
            let _ = writeln!(s, "{n}-by-{n}, nzmax: {nnz} nnz: {nnz}, 1-norm: {one_norm}");
            let mut k = 0;
            for j in 0..n {
                let start = k;
                while k < nnz && entries[k].1 == j {
                    k += 1;
                }
                let _ = writeln!(s, "    col {j} : locations {start} to {}", k as i64 - 1);
                for &(i, _, v) in &entries[start..k] {
                    let _ = writeln!(s, "      {i} : {v:.17e}");
                }
            }
        }
    }
    for v in &problem.q {
        let _ = write!(s, " {v:.17e} ");
    }
    s.push('\n');
    for v in &problem.mu {
        let _ = write!(s, " {v:.17e} ");
    }
    s.push('\n');
    s
}

/// Parses problem text (for tests and fuzzing); errors are rendered as in [`read_fc2d`].
pub fn parse_fc2d_str(text: &str) -> Result<ContactProblem, String> {
    parse_fc2d(text).map_err(|e| match e {
        Ok(ParseError { line, msg }) => format!("line {line}: {msg}"),
        Err(msg) => msg,
    })
}
