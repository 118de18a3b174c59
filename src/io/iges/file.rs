//! The fixed-form ASCII layout of an IGES file: 80-column lines whose column 73 names the
//! section (Start, Global, Directory, Parameter, Terminate), the global section's
//! delimiters and units, directory entries (two lines of ten 8-column fields each) and
//! parameter records (free-format fields in columns 1–64, Hollerith strings `nH…` kept
//! whole). Nothing here knows what an entity means; `entities.rs` does.

use crate::error::{Error, Result};
use std::ops::Range;

/// One line of a section: its data columns and its 1-based line in the file.
#[derive(Clone, Copy)]
struct Line<'a> {
    number: usize,
    data: &'a [u8],
}

/// The sections of a file, split and checked for order.
pub(super) struct Sections<'a> {
    global: Vec<Line<'a>>,
    directory: Vec<Line<'a>>,
    parameters: Vec<Line<'a>>,
}

/// Columns 1–72 hold data; column 73 the section letter; 74–80 a sequence number.
const DATA_COLUMNS: usize = 72;
/// In the parameter section, columns 65–72 point back at the directory entry.
const PARAMETER_COLUMNS: usize = 64;

impl<'a> Sections<'a> {
    /// Splits `bytes` into sections by column 73, refusing the compressed and binary forms,
    /// short lines and sections out of order (S, G, D, P, T).
    pub(super) fn split(bytes: &'a [u8]) -> Result<Self> {
        let mut sections = Sections {
            global: Vec::new(),
            directory: Vec::new(),
            parameters: Vec::new(),
        };
        let mut last_rank = 0;
        for (index, raw) in bytes.split(|&b| b == b'\n').enumerate() {
            let number = index + 1;
            let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
            if raw.iter().all(u8::is_ascii_whitespace) {
                continue;
            }
            let Some(&letter) = raw.get(DATA_COLUMNS) else {
                return Err(Error::syntax(format!(
                    "the line has {} columns: IGES lines are 80 columns, column 73 naming the section (S, G, D, P or T)",
                    raw.len()
                ))
                .at_line(number));
            };
            let rank = match letter {
                b'S' => 1,
                b'G' => 2,
                b'D' => 3,
                b'P' => 4,
                b'T' => 5,
                b'C' => {
                    return Err(Error::syntax(
                        "this is the compressed ASCII form of IGES (section letter C): only the fixed 80-column form is read",
                    )
                    .at_line(number));
                }
                other => {
                    let columns = if raw.len() == 80 {
                        String::new()
                    } else {
                        format!(" (the line has {} columns, not 80)", raw.len())
                    };
                    return Err(Error::syntax(format!(
                        "column 73 is {:?}: it must name the section (S, G, D, P or T){columns}",
                        char::from(other)
                    ))
                    .at_line(number));
                }
            };
            if rank < last_rank {
                return Err(Error::syntax(format!(
                    "a {} line after the sections that follow it: the order is S, G, D, P, T",
                    char::from(letter)
                ))
                .at_line(number));
            }
            last_rank = rank;
            let line = Line {
                number,
                data: &raw[..DATA_COLUMNS],
            };
            match letter {
                b'G' => sections.global.push(line),
                b'D' => sections.directory.push(line),
                b'P' => sections.parameters.push(line),
                _ => {}
            }
        }
        if sections.directory.is_empty() {
            return Err(Error::syntax(
                "no directory section (lines with D in column 73): this is not an IGES file",
            ));
        }
        if !sections.directory.len().is_multiple_of(2) {
            let last = sections.directory[sections.directory.len() - 1];
            return Err(Error::syntax(
                "the directory section has an odd number of lines: each entry takes two",
            )
            .at_line(last.number));
        }
        Ok(sections)
    }

    /// The global section's delimiters and length unit.
    pub(super) fn global(&self) -> Result<Global> {
        let mut text = Vec::new();
        for line in &self.global {
            text.extend_from_slice(line.data);
        }
        let line_of = |_| self.global.first().map_or(1, |l| l.number);
        // Fields 1 and 2 name the delimiters as `1Hc`; empty, they default to `,` and `;`.
        let mut at = skip_blanks(&text, 0);
        let delimiter = |at: &mut usize, default: u8, separator: u8| -> Result<u8> {
            let chosen = if text.get(*at..*at + 2) == Some(b"1H") {
                let c = *text.get(*at + 2).ok_or_else(|| {
                    Error::syntax("the global section ends inside a delimiter").at_line(line_of(()))
                })?;
                *at = skip_blanks(&text, *at + 3);
                c
            } else {
                default
            };
            // The field ends at the parameter delimiter (the record's end also ends it).
            match text.get(*at) {
                Some(&c) if c == separator || c == b';' => *at += 1,
                _ => {}
            }
            Ok(chosen)
        };
        let parameter = delimiter(&mut at, b',', b',')?;
        let record = delimiter(&mut at, b';', parameter)?;
        let mut global = Global {
            parameter,
            record,
            unit_to_mm: None,
        };
        if parameter == record
            || parameter.is_ascii_alphanumeric()
            || record.is_ascii_alphanumeric()
        {
            return Err(Error::syntax(format!(
                "the global section names {:?} and {:?} as delimiters: they must be two different non-alphanumeric characters",
                char::from(parameter),
                char::from(record)
            ))
            .at_line(line_of(())));
        }
        // Fields 3 onwards; a file may end the section early (all defaults).
        let rest = &text[at.min(text.len())..];
        let (ranges, _) = scan_fields(rest, global.parameter, global.record);
        let fields: Vec<&[u8]> = ranges.into_iter().map(|r| &rest[r]).collect();
        // Fields 14 (unit flag) and 15 (unit name) are fields[11] and fields[12].
        let flag = fields.get(11).and_then(|f| parse_integer(f).ok());
        let name = fields
            .get(12)
            .and_then(|f| hollerith(f))
            .map(|s| s.trim().to_ascii_uppercase());
        global.unit_to_mm = match (flag, name.as_deref()) {
            (Some(3), Some(name)) => unit_named(name),
            (Some(flag), _) => unit_flag(flag),
            (None, Some(name)) => unit_named(name),
            (None, None) => None,
        };
        if flag.is_some_and(|f| unit_flag(f).is_none() && f != 3) {
            return Err(Error::syntax(format!(
                "global field 14 (units flag) is {}: IGES defines 1 to 11",
                flag.unwrap_or_default()
            ))
            .at_line(line_of(())));
        }
        Ok(global)
    }

    /// The directory entries, in file order (entry k has sequence number 2k + 1).
    pub(super) fn directory(&self) -> Result<Vec<DirectoryEntry>> {
        self.directory
            .chunks_exact(2)
            .enumerate()
            .map(|(k, pair)| DirectoryEntry::parse(2 * k + 1, pair[0], pair[1]))
            .collect()
    }

    /// The parameter record of `entry`: its fields (the entity type first), each with the
    /// file line it starts on. The record starts on parameter line `entry.parameter_start`
    /// (counted in the section, as conforming files number them) and runs to the record
    /// delimiter; its first field must repeat the entry's type.
    pub(super) fn record(&self, entry: &DirectoryEntry, global: &Global) -> Result<Record> {
        let start = entry.parameter_start;
        if start == 0 || start > self.parameters.len() {
            return Err(Error::syntax(format!(
                "its parameter data pointer is {start}, but the parameter section has {} lines",
                self.parameters.len()
            ))
            .at_line(entry.line));
        }
        let mut text = Vec::new();
        let mut starts = Vec::new();
        let mut end = None;
        for line in &self.parameters[start - 1..] {
            starts.push((text.len(), line.number));
            let data = &line.data[..PARAMETER_COLUMNS];
            text.extend_from_slice(data);
            // Scan the whole record only once a line holds a delimiter (it may sit inside a
            // Hollerith string): records run to thousands of lines.
            if !data.contains(&global.record) {
                continue;
            }
            let (ranges, ended) = scan_fields(&text, global.parameter, global.record);
            if ended.is_some() {
                end = Some(ranges);
                break;
            }
        }
        let Some(ranges) = end else {
            return Err(Error::syntax(format!(
                "the parameter record starting on parameter line {start} has no record delimiter {:?}",
                char::from(global.record)
            ))
            .at_line(self.parameters[start - 1].number));
        };
        let line_at = |offset: usize| {
            let k = starts.partition_point(|&(o, _)| o <= offset);
            starts[k.saturating_sub(1)].1
        };
        let record = Record {
            fields: ranges
                .into_iter()
                .map(|r| (text[r.clone()].to_vec(), line_at(r.start)))
                .collect(),
            line: self.parameters[start - 1].number,
        };
        let kind = record.integer(0)?;
        if kind != i64::from(entry.kind) {
            return Err(Error::syntax(format!(
                "the parameter record on parameter line {start} is of entity type {kind}, but its directory entry says {}",
                entry.kind
            ))
            .at_line(record.line));
        }
        Ok(record)
    }
}

/// What the global section sets.
#[derive(Clone, Copy, Debug)]
pub(super) struct Global {
    pub parameter: u8,
    pub record: u8,
    /// Millimetres per model unit; `None` when the file names no unit.
    pub unit_to_mm: Option<f64>,
}

/// Millimetres per unit of the global section's units flag (field 14).
fn unit_flag(flag: i64) -> Option<f64> {
    Some(match flag {
        1 => 25.4,
        2 => 1.0,
        4 => 304.8,
        5 => 1_609_344.0,
        6 => 1000.0,
        7 => 1_000_000.0,
        8 => 0.0254,
        9 => 0.001,
        10 => 10.0,
        11 => 0.0000254,
        _ => return None,
    })
}

/// Millimetres per unit of a unit name (field 15, used with flag 3).
fn unit_named(name: &str) -> Option<f64> {
    let flag = match name {
        "IN" | "INCH" => 1,
        "MM" => 2,
        "FT" => 4,
        "MI" => 5,
        "M" => 6,
        "KM" => 7,
        "MIL" => 8,
        "UM" => 9,
        "CM" => 10,
        "UIN" => 11,
        _ => return None,
    };
    unit_flag(flag)
}

/// Entity-use flag 05: the entity lives in some surface's parameter space.
pub(super) const USE_PARAMETRIC: u8 = 5;

/// One directory entry (two lines, 8-column fields).
#[derive(Clone, Debug)]
pub(super) struct DirectoryEntry {
    /// The entry's sequence number (2k + 1 for the k-th entry): what pointers name.
    pub sequence: usize,
    /// The file line of its first line.
    pub line: usize,
    pub kind: u32,
    pub form: i64,
    /// 1-based line in the parameter section where its record starts.
    pub parameter_start: usize,
    /// Pointer to a 124 transformation (0: none).
    pub transform: i64,
    /// Entity-use flag (status digits 5–6): 0 geometry, 5 parametric, 6 construction, …
    pub usage: u8,
    /// Label (field 18) and subscript (field 19), as written.
    pub label: String,
    pub subscript: i64,
}

impl DirectoryEntry {
    fn parse(sequence: usize, first: Line, second: Line) -> Result<Self> {
        fn field<'a>(line: Line<'a>, k: usize) -> &'a [u8] {
            &line.data[8 * k..8 * k + 8]
        }
        let integer = |line: Line, k: usize, name: &str| -> Result<i64> {
            let text = field(line, k);
            if text.iter().all(u8::is_ascii_whitespace) {
                return Ok(0);
            }
            parse_integer(text).map_err(|_| {
                Error::syntax(format!(
                    "directory field {} ({name}) is {:?}: it must be an integer",
                    k + 1 + if line.number == first.number { 0 } else { 9 },
                    String::from_utf8_lossy(text).trim()
                ))
                .at_line(line.number)
            })
        };
        let kind = integer(first, 0, "entity type")?;
        let repeated = integer(second, 0, "entity type")?;
        if kind != repeated || !(0..=10_000).contains(&kind) {
            return Err(Error::syntax(format!(
                "the directory entry's two lines name entity types {kind} and {repeated}"
            ))
            .at_line(first.number));
        }
        let parameter_start = integer(first, 1, "parameter data")?;
        let status = field(first, 8);
        let usage = status
            .get(4..6)
            .and_then(|d| std::str::from_utf8(d).ok())
            .and_then(|d| d.trim().parse::<u8>().ok())
            .unwrap_or(0);
        Ok(DirectoryEntry {
            sequence,
            line: first.number,
            kind: kind as u32,
            form: integer(second, 4, "form number")?,
            parameter_start: usize::try_from(parameter_start).unwrap_or(0),
            transform: integer(first, 6, "transformation matrix")?,
            usage,
            label: String::from_utf8_lossy(field(second, 7)).trim().to_string(),
            subscript: integer(second, 8, "entity subscript").unwrap_or(0),
        })
    }
}

/// A parameter record: its fields (field 0 is the entity type; 1, 2, … the parameters as
/// the specification numbers them), each with the file line it starts on.
pub(super) struct Record {
    fields: Vec<(Vec<u8>, usize)>,
    /// The line the record starts on.
    pub line: usize,
}

impl Record {
    /// The number of fields, the entity type included.
    pub fn len(&self) -> usize {
        self.fields.len()
    }

    fn field(&self, k: usize) -> Result<(&[u8], usize)> {
        self.fields
            .get(k)
            .map(|(text, line)| (text.as_slice(), *line))
            .ok_or_else(|| {
                Error::syntax(format!(
                    "the record ends after {} parameters; parameter {k} is missing",
                    self.fields.len().saturating_sub(1)
                ))
                .at_line(self.line)
            })
    }

    /// Parameter `k` as a real (blank: 0); `D` exponents accepted.
    pub fn real(&self, k: usize) -> Result<f64> {
        let (text, line) = self.field(k)?;
        let trimmed = trim(text);
        if trimmed.is_empty() {
            return Ok(0.0);
        }
        let normal: String = trimmed
            .iter()
            .map(|&b| match b {
                b'D' | b'd' => 'E',
                other => char::from(other),
            })
            .collect();
        match normal.parse::<f64>() {
            Ok(value) if value.is_finite() => Ok(value),
            _ => Err(Error::syntax(format!(
                "parameter {k} is {:?}: a finite real number is expected",
                String::from_utf8_lossy(trimmed)
            ))
            .at_line(line)),
        }
    }

    /// Parameter `k` as an integer (blank: 0; a real with no fraction is accepted).
    pub fn integer(&self, k: usize) -> Result<i64> {
        let (text, line) = self.field(k)?;
        if trim(text).is_empty() {
            return Ok(0);
        }
        parse_integer(text).map_err(|_| {
            Error::syntax(format!(
                "parameter {k} is {:?}: an integer is expected",
                String::from_utf8_lossy(trim(text))
            ))
            .at_line(line)
        })
    }

    /// Parameter `k` as a count in `0..=limit` (what the rest of the record can hold): a
    /// count is never trusted further than the data that follows it.
    pub fn count(&self, k: usize, limit: usize) -> Result<usize> {
        let value = self.integer(k)?;
        match usize::try_from(value) {
            Ok(n) if n <= limit => Ok(n),
            _ => Err(Error::syntax(format!(
                "parameter {k} is {value}: the record has room for at most {limit}"
            ))
            .at_line(self.field(k)?.1)),
        }
    }

    /// The file line of parameter `k` (the record's first line if it has none).
    pub fn line_of(&self, k: usize) -> usize {
        self.fields.get(k).map_or(self.line, |f| f.1)
    }
}

fn trim(text: &[u8]) -> &[u8] {
    text.trim_ascii()
}

fn parse_integer(text: &[u8]) -> std::result::Result<i64, ()> {
    let text = std::str::from_utf8(trim(text)).map_err(|_| ())?;
    if let Ok(n) = text.parse::<i64>() {
        return Ok(n);
    }
    // Some writers put integers as reals ("3." or "3.0").
    let real: f64 = text.replace(['D', 'd'], "E").parse().map_err(|_| ())?;
    if real.fract() == 0.0 && real.abs() < 1e15 {
        Ok(real as i64)
    } else {
        Err(())
    }
}

/// The text of a Hollerith field `nH…`, if it is one.
fn hollerith(field: &[u8]) -> Option<String> {
    let field = trim(field);
    let h = field.iter().position(|&b| b == b'H' || b == b'h')?;
    let n: usize = std::str::from_utf8(&field[..h]).ok()?.parse().ok()?;
    let text = field.get(h + 1..h + 1 + n)?;
    Some(String::from_utf8_lossy(text).into_owned())
}

fn skip_blanks(text: &[u8], mut at: usize) -> usize {
    while text.get(at) == Some(&b' ') {
        at += 1;
    }
    at
}

/// Where a Hollerith string `nH…` starting at `at` ends, if one starts there.
fn hollerith_end(text: &[u8], at: usize) -> Option<usize> {
    let digits = text[at..].iter().take_while(|b| b.is_ascii_digit()).count();
    if digits == 0 || !matches!(text.get(at + digits), Some(b'H' | b'h')) {
        return None;
    }
    let n: usize = std::str::from_utf8(&text[at..at + digits])
        .ok()?
        .parse()
        .ok()?;
    Some((at + digits + 1).saturating_add(n).min(text.len()))
}

/// The fields of `text` as byte ranges, up to the first record delimiter outside a
/// Hollerith string (recognised only at a field's start), and the offset just past that
/// delimiter (`None`: the record has not ended within `text`).
fn scan_fields(text: &[u8], parameter: u8, record: u8) -> (Vec<Range<usize>>, Option<usize>) {
    let mut fields = Vec::new();
    let mut start = 0;
    let mut at = skip_blanks(text, 0);
    let mut at_field_start = true;
    while at < text.len() {
        if at_field_start && let Some(end) = hollerith_end(text, at) {
            at = end;
            at_field_start = false;
            continue;
        }
        at_field_start = false;
        let c = text[at];
        if c == parameter || c == record {
            fields.push(start..at);
            if c == record {
                return (fields, Some(at + 1));
            }
            start = at + 1;
            at = skip_blanks(text, start);
            at_field_start = true;
            continue;
        }
        at += 1;
    }
    if !trim(&text[start.min(text.len())..]).is_empty() {
        fields.push(start..text.len());
    }
    (fields, None)
}
