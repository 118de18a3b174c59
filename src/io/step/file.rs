//! The exchange structure of ISO 10303-21 (a STEP file's text form): the DATA section's
//! instances `#id = TYPE(params);` and complex instances `#id = (A(..) B(..));`, parsed into
//! untyped records that the entity layer reads by name and position.
//!
//! Statements are found by one sequential scan (strings, comments and the HEADER section
//! skipped), then parsed in parallel: parsing is the slow part of a multi-megabyte file.

use crate::error::{Error, Result};
use rayon::prelude::*;
use std::collections::HashMap;

/// A parameter value.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// `#id`.
    Ref(u64),
    /// An integer (no decimal point).
    Integer(i64),
    /// A real (with a decimal point or exponent).
    Real(f64),
    /// `'text'`, with `''` read as one apostrophe.
    Text(String),
    /// `.NAME.` (enumerations and the logicals .T., .F., .U.).
    Enum(String),
    /// `(a, b, …)`.
    List(Vec<Value>),
    /// `TYPE(value)`: a typed value such as `LENGTH_MEASURE(25.4)`.
    Typed(String, Vec<Value>),
    /// `$`: not given.
    Unset,
    /// `*`: derived by the schema.
    Derived,
}

/// One record: an entity type name and its parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Record {
    pub name: String,
    pub params: Vec<Value>,
}

/// One instance of the DATA section: a simple record, or the records of a complex
/// (multi-type) instance in file order.
#[derive(Clone, Debug)]
pub struct Instance {
    pub records: Vec<Record>,
    /// 1-based line of the instance's `#id`.
    pub line: usize,
}

impl Instance {
    /// The record of type `name`, if the instance has one.
    pub fn record(&self, name: &str) -> Option<&Record> {
        self.records.iter().find(|r| r.name == name)
    }

    /// The type name (a complex instance: its records' names joined by `+`).
    pub fn kind(&self) -> String {
        let names: Vec<&str> = self.records.iter().map(|r| r.name.as_str()).collect();
        names.join("+")
    }
}

/// The instances of a file by id.
#[derive(Debug, Default)]
pub struct ExchangeFile {
    pub instances: HashMap<u64, Instance>,
}

/// Deepest nesting of parenthesised lists a parameter may have.
const MAX_NESTING: usize = 64;

/// A statement of the DATA section: its text and first line.
struct Statement<'a> {
    text: &'a str,
    line: usize,
}

impl ExchangeFile {
    /// Parses the text of a STEP file. Errors carry the 1-based line
    /// ([`Error::AtLine`]); a file without `ISO-10303-21;` or a DATA section is refused.
    pub fn parse(text: &str) -> Result<Self> {
        let trimmed = text.trim_start_matches('\u{feff}').trim_start();
        if !trimmed.starts_with("ISO-10303-21") {
            return Err(Error::Syntax {
                message: "not a STEP file: it does not start with ISO-10303-21;".into(),
            });
        }
        let statements = split_statements(text)?;
        let parsed: Vec<Result<(u64, Instance)>> = statements
            .par_iter()
            .with_min_len(256)
            .map(|s| parse_instance(s.text, s.line).map_err(|e| e.at_line(s.line)))
            .collect();
        let mut instances = HashMap::with_capacity(parsed.len());
        for result in parsed {
            let (id, instance) = result?;
            let line = instance.line;
            if instances.insert(id, instance).is_some() {
                return Err(Error::Syntax {
                    message: format!("instance #{id} is defined twice"),
                }
                .at_line(line));
            }
        }
        Ok(ExchangeFile { instances })
    }
}

/// The statements (`#…;`) of every DATA section, each with its first line.
fn split_statements(text: &str) -> Result<Vec<Statement<'_>>> {
    let bytes = text.as_bytes();
    let mut statements = Vec::new();
    let (mut k, mut line) = (0usize, 1usize);
    let mut in_data = false;
    let mut start: Option<(usize, usize)> = None;
    let mut keyword_start = 0usize;
    while k < bytes.len() {
        match bytes[k] {
            b'\n' => line += 1,
            b'\'' => {
                // A string: '' is an escaped apostrophe.
                let opened = line;
                k += 1;
                loop {
                    match bytes.get(k) {
                        None => {
                            return Err(Error::Syntax {
                                message: "a string is not closed".into(),
                            }
                            .at_line(opened));
                        }
                        Some(b'\'') if bytes.get(k + 1) == Some(&b'\'') => k += 1,
                        Some(b'\'') => break,
                        Some(b'\n') => line += 1,
                        _ => {}
                    }
                    k += 1;
                }
            }
            b'/' if bytes.get(k + 1) == Some(&b'*') => {
                let opened = line;
                k += 2;
                while !(bytes.get(k) == Some(&b'*') && bytes.get(k + 1) == Some(&b'/')) {
                    match bytes.get(k) {
                        None => {
                            return Err(Error::Syntax {
                                message: "a comment is not closed".into(),
                            }
                            .at_line(opened));
                        }
                        Some(b'\n') => line += 1,
                        _ => {}
                    }
                    k += 1;
                }
                k += 1;
            }
            b'#' if in_data && start.is_none() => start = Some((k, line)),
            b';' => {
                if let Some((from, first_line)) = start.take() {
                    statements.push(Statement {
                        text: &text[from..k],
                        line: first_line,
                    });
                } else {
                    let keyword = text[keyword_start..k].trim();
                    if keyword.eq_ignore_ascii_case("DATA") || keyword.starts_with("DATA(") {
                        in_data = true;
                    } else if keyword.eq_ignore_ascii_case("ENDSEC") {
                        in_data = false;
                    }
                }
                keyword_start = k + 1;
            }
            _ => {}
        }
        k += 1;
    }
    if let Some((_, first_line)) = start {
        return Err(Error::UnexpectedEnd {
            expected: "';' closing the instance".into(),
        }
        .at_line(first_line));
    }
    if statements.is_empty() {
        return Err(Error::Syntax {
            message: "the file has no DATA section with instances".into(),
        });
    }
    Ok(statements)
}

/// Parses `#id = …` (without its `;`).
fn parse_instance(text: &str, line: usize) -> Result<(u64, Instance)> {
    let mut parser = Parser {
        text: text.as_bytes(),
        at: 1,
    };
    let id = parser.integer_digits()?;
    parser.expect(b'=')?;
    parser.skip_space();
    let records = if parser.peek() == Some(b'(') {
        parser.at += 1;
        let mut records = Vec::new();
        loop {
            parser.skip_space();
            if parser.peek() == Some(b')') {
                parser.at += 1;
                break;
            }
            records.push(parser.record()?);
        }
        records
    } else {
        vec![parser.record()?]
    };
    parser.skip_space();
    if parser.at != parser.text.len() {
        return Err(parser.error("text after the instance's parameters"));
    }
    if records.is_empty() {
        return Err(parser.error("a complex instance with no records"));
    }
    Ok((id, Instance { records, line }))
}

struct Parser<'a> {
    text: &'a [u8],
    at: usize,
}

impl Parser<'_> {
    fn error(&self, what: &str) -> Error {
        let shown = String::from_utf8_lossy(&self.text[self.at.min(self.text.len())..])
            .chars()
            .take(24)
            .collect::<String>();
        Error::Syntax {
            message: format!("{what} at `{shown}`"),
        }
    }

    fn peek(&self) -> Option<u8> {
        self.text.get(self.at).copied()
    }

    fn skip_space(&mut self) {
        loop {
            match self.peek() {
                Some(c) if c.is_ascii_whitespace() => self.at += 1,
                Some(b'/') if self.text.get(self.at + 1) == Some(&b'*') => {
                    while self.at < self.text.len()
                        && !(self.text[self.at] == b'*'
                            && self.text.get(self.at + 1) == Some(&b'/'))
                    {
                        self.at += 1;
                    }
                    self.at = (self.at + 2).min(self.text.len());
                }
                _ => return,
            }
        }
    }

    fn expect(&mut self, c: u8) -> Result<()> {
        self.skip_space();
        if self.peek() == Some(c) {
            self.at += 1;
            Ok(())
        } else {
            Err(self.error(&format!("expected '{}'", c as char)))
        }
    }

    fn integer_digits(&mut self) -> Result<u64> {
        let start = self.at;
        while self.peek().is_some_and(|c| c.is_ascii_digit()) {
            self.at += 1;
        }
        std::str::from_utf8(&self.text[start..self.at])
            .ok()
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| self.error("expected an instance number"))
    }

    fn keyword(&mut self) -> Result<String> {
        self.skip_space();
        let start = self.at;
        if self.peek() == Some(b'!') {
            self.at += 1;
        }
        while self
            .peek()
            .is_some_and(|c| c.is_ascii_alphanumeric() || c == b'_' || c == b'-')
        {
            self.at += 1;
        }
        if self.at == start {
            return Err(self.error("expected an entity type name"));
        }
        Ok(String::from_utf8_lossy(&self.text[start..self.at]).to_ascii_uppercase())
    }

    /// `NAME(params)`.
    fn record(&mut self) -> Result<Record> {
        let name = self.keyword()?;
        let params = self.list(0)?;
        Ok(Record { name, params })
    }

    /// `( value, … )`.
    fn list(&mut self, depth: usize) -> Result<Vec<Value>> {
        if depth > MAX_NESTING {
            return Err(self.error("lists nested too deeply"));
        }
        self.expect(b'(')?;
        let mut values = Vec::new();
        self.skip_space();
        if self.peek() == Some(b')') {
            self.at += 1;
            return Ok(values);
        }
        loop {
            values.push(self.value(depth)?);
            self.skip_space();
            match self.peek() {
                Some(b',') => self.at += 1,
                Some(b')') => {
                    self.at += 1;
                    return Ok(values);
                }
                _ => return Err(self.error("expected ',' or ')'")),
            }
        }
    }

    fn value(&mut self, depth: usize) -> Result<Value> {
        self.skip_space();
        match self.peek() {
            Some(b'#') => {
                self.at += 1;
                Ok(Value::Ref(self.integer_digits()?))
            }
            Some(b'$') => {
                self.at += 1;
                Ok(Value::Unset)
            }
            Some(b'*') => {
                self.at += 1;
                Ok(Value::Derived)
            }
            Some(b'(') => Ok(Value::List(self.list(depth + 1)?)),
            Some(b'\'') => self.text_value(),
            Some(b'"') => {
                // Binary: kept as its hex digits.
                self.at += 1;
                let start = self.at;
                while self.peek().is_some_and(|c| c != b'"') {
                    self.at += 1;
                }
                let hex = String::from_utf8_lossy(&self.text[start..self.at]).into_owned();
                self.expect(b'"')?;
                Ok(Value::Text(hex))
            }
            Some(b'.') => {
                self.at += 1;
                let start = self.at;
                while self
                    .peek()
                    .is_some_and(|c| c.is_ascii_alphanumeric() || c == b'_')
                {
                    self.at += 1;
                }
                let name = String::from_utf8_lossy(&self.text[start..self.at]).to_ascii_uppercase();
                self.expect(b'.')?;
                Ok(Value::Enum(name))
            }
            Some(c) if c == b'-' || c == b'+' || c.is_ascii_digit() => self.number(),
            Some(c) if c.is_ascii_alphabetic() || c == b'!' => {
                let name = self.keyword()?;
                Ok(Value::Typed(name, self.list(depth + 1)?))
            }
            _ => Err(self.error("expected a parameter")),
        }
    }

    fn text_value(&mut self) -> Result<Value> {
        self.at += 1;
        let mut bytes = Vec::new();
        loop {
            match self.peek() {
                None => return Err(self.error("a string is not closed")),
                Some(b'\'') if self.text.get(self.at + 1) == Some(&b'\'') => {
                    bytes.push(b'\'');
                    self.at += 2;
                }
                Some(b'\'') => {
                    self.at += 1;
                    return Ok(Value::Text(String::from_utf8_lossy(&bytes).into_owned()));
                }
                Some(c) => {
                    if c != b'\n' && c != b'\r' {
                        bytes.push(c);
                    }
                    self.at += 1;
                }
            }
        }
    }

    fn number(&mut self) -> Result<Value> {
        let start = self.at;
        let mut real = false;
        while let Some(c) = self.peek() {
            match c {
                b'0'..=b'9' | b'+' | b'-' => {}
                b'.' | b'E' | b'e' => real = true,
                _ => break,
            }
            self.at += 1;
        }
        let digits = std::str::from_utf8(&self.text[start..self.at]).unwrap_or("");
        let parsed = if real {
            // Part 21 allows "1." and "1.E5".
            digits.parse::<f64>().ok().map(Value::Real)
        } else {
            digits.parse::<i64>().ok().map(Value::Integer)
        };
        parsed.ok_or_else(|| Error::Syntax {
            message: format!("`{digits}` is not a number"),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMALL: &str = "ISO-10303-21;\nHEADER;\nFILE_NAME('a;b','',(''),(''),'','','');\nENDSEC;\nDATA;\n\
        #1=CARTESIAN_POINT('it''s',(0.,1.5E1,-2.));\n/* a comment; with a semicolon */\n\
        #2 = ( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) );\n\
        #3=MEASURE(LENGTH_MEASURE(25.4),#2,$,3);\nENDSEC;\nEND-ISO-10303-21;\n";

    #[test]
    fn parses_simple_complex_and_typed_values() {
        let file = ExchangeFile::parse(SMALL).unwrap();
        assert_eq!(file.instances.len(), 3);
        let point = &file.instances[&1];
        assert_eq!(point.line, 6);
        assert_eq!(
            point.records[0].params,
            vec![
                Value::Text("it's".into()),
                Value::List(vec![Value::Real(0.0), Value::Real(15.0), Value::Real(-2.0)])
            ]
        );
        let unit = &file.instances[&2];
        assert_eq!(unit.kind(), "LENGTH_UNIT+NAMED_UNIT+SI_UNIT");
        assert_eq!(
            unit.record("SI_UNIT").unwrap().params,
            vec![Value::Enum("MILLI".into()), Value::Enum("METRE".into())]
        );
        assert_eq!(
            file.instances[&3].records[0].params,
            vec![
                Value::Typed("LENGTH_MEASURE".into(), vec![Value::Real(25.4)]),
                Value::Ref(2),
                Value::Unset,
                Value::Integer(3)
            ]
        );
    }

    #[test]
    fn refuses_broken_text_with_its_line() {
        let cases = [
            ("ISO-10303-21;\nDATA;\n#1=POINT((0.,1.);\nENDSEC;\n", 3),
            ("ISO-10303-21;\nDATA;\n#1=POINT('open);\nENDSEC;\n", 3),
            (
                "ISO-10303-21;\nDATA;\n#1=POINT(1.);\n#1=POINT(2.);\nENDSEC;\n",
                4,
            ),
            ("ISO-10303-21;\nDATA;\n\n#1=POINT(1.e)\n", 4),
        ];
        for (text, line) in cases {
            match ExchangeFile::parse(text) {
                Err(Error::AtLine { line: at, .. }) => assert_eq!(at, line, "{text}"),
                other => panic!("{text}: {other:?}"),
            }
        }
        assert!(ExchangeFile::parse("solid x\nendsolid").is_err());
    }
}
