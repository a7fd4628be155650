//! The log reader's tests: whole texts read every way (csv parser, plain lines, fast rows,
//! streamed summary), each row and each error compared.
#![allow(clippy::float_cmp)] // values parsed from short decimal text compare exactly
use super::header::LOOKAHEAD_ROWS;
use super::schema::STDIN_NAME;
use super::units::time_unit_not_seconds;
use super::units::unit_in_name;
use super::*;
use std::io::{self, Read};

fn read(text: &str) -> Result<Log, LogError> {
    Log::from_reader("t.csv", text.as_bytes(), &ColumnMap::default())
}

#[test]
fn summary_counts_rows_and_ranges_by_hand() {
    // Reference: 4 rows, 3 measured (the third has an empty bias), tracks 50..400, time 0.5..3.
    let text = "time_s,track,bias\n0.5,100,1\n1,400,2\n2,50,\n3,200,4\n";
    let mut r = LogReader::from_reader("t.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
    let s = r.summarise().unwrap();
    assert_eq!((s.rows, s.measured), (4, 3));
    assert_eq!((s.positions, s.times_s), ([50.0, 400.0], [0.5, 3.0]));
    // Bad rows fail the summary just as they fail reading.
    let bad = "time_s,track,bias\n1,100,1\n0,200,2\n";
    let mut r = LogReader::from_reader("t.csv", bad.as_bytes(), &ColumnMap::default()).unwrap();
    assert!(r.summarise().unwrap_err().to_string().contains("line 3"));
}

#[test]
fn reads_metadata_covariates_and_unmeasured_rows() {
    let log = read("# generator = biasctl\n# seed: 7\ntime_s,track,bias,temp_c\n0,1,2,3\n1,2,,4\n")
        .unwrap();
    assert_eq!(log.schema.metadata_value("seed"), Some("7"));
    assert_eq!(log.schema.metadata_value("generator"), Some("biasctl"));
    assert_eq!(log.len(), 2);
    assert_eq!(log.row(0).line, 4);
    assert_eq!(log.row(1).line, 5);
    assert_eq!(log.row(1).bias, None);
    assert_eq!(log.row(1).covariates, vec![4.0]);
    assert_eq!(log.measured_count(), 1);
}

#[test]
fn column_map_renames_required_columns() {
    let map = ColumnMap {
        time: "t".into(),
        track: "position_m".into(),
        bias: "force_N".into(),
        delimiter: None,
    };
    let log = Log::from_reader(
        "r.csv",
        "force_N,t,position_m,v\n1.5,0,0.001,2\n".as_bytes(),
        &map,
    )
    .unwrap();
    assert_eq!(log.row(0).track, 0.001);
    assert_eq!(log.row(0).bias, Some(1.5));
    assert_eq!(log.schema.covariates, vec!["v".to_string()]);
}

#[test]
fn every_bad_input_names_line_and_column() {
    let cases: &[(&str, &str)] = &[
        ("", "empty"),
        ("# only metadata\n", "empty"),
        ("time_s,track\n0,1\n", "missing required column `bias`"),
        (
            "time_s,track,bias\n0,1,x\n",
            "line 2, column 3 (`bias`): not a number: `x`",
        ),
        (
            "time_s,track,bias\n0,NaN,1\n",
            "line 2, column 2 (`track`): not a finite number",
        ),
        ("time_s,track,bias\n0,inf,1\n", "not a finite number"),
        (
            "time_s,track,bias\n1,1,1\n0.5,2,1\n",
            "line 3, column 1 (`time_s`): time goes backwards",
        ),
        ("time_s,track,bias\n0,1,\n1,2,\n", "no measured rows"),
        ("time_s,track,bias\n", "no rows under the header"),
        ("time_s,track,bias\n0,1,1,5\n", "line 2: 4 fields"),
        (
            "time_s,track,bias\n0,,1\n",
            "line 2, column 2 (`track`): empty cell",
        ),
        ("time_s,track,bias,track\n0,1,1,1\n", "appears twice"),
    ];
    for (text, want) in cases {
        let err = read(text).expect_err(text).to_string();
        assert!(
            err.contains(want),
            "input {text:?}: got `{err}`, want `{want}`"
        );
        assert!(err.starts_with("t.csv"), "{err}");
    }
}

/// The physical line of byte `at` of `text`: 1 + the line ends before it, as an editor
/// shows them (`\n`, a lone `\r`, and `\r\n` as one, counted at its `\n`). The slow,
/// obvious reference for line numbers.
fn physical_line(text: &[u8], at: usize) -> u64 {
    let lone_cr = |i: usize| text[i] == b'\r' && text.get(i + 1) != Some(&b'\n');
    1 + (0..at).filter(|&i| text[i] == b'\n' || lone_cr(i)).count() as u64
}

#[test]
fn errors_name_the_physical_line_after_blank_lines_crlf_and_quoted_newlines() {
    // Reference: each bad cell is marked `x` (or `@` for a row of the wrong length); its
    // line is counted by hand in the raw bytes (`physical_line`), its column is the field.
    // Read every way: all through the csv parser (reference), plain lines row by row, fast
    // rows, the streaming summary (`check`), from sources handing out 1, 3 or all bytes.
    let cases: &[(&str, &str)] = &[
        // Blank lines before the bad row (the csv fallback).
        (
            "time_s,track,bias\n0,1,1\n\n\n1,x,1\n",
            "line 5, column 2 (`track`)",
        ),
        // Blank lines after it.
        (
            "time_s,track,bias\n0,1,1\n1,1,x\n\n\n2,1,1\n",
            "line 3, column 3 (`bias`)",
        ),
        // Blank lines before and after, then a later bad row.
        (
            "time_s,track,bias\n\n0,1,1\n\n1,1,1\n\n\n2,x,1\n\n",
            "line 8, column 2 (`track`)",
        ),
        // Blank lines right after the header.
        (
            "time_s,track,bias\n\n\n0,1,x\n",
            "line 4, column 3 (`bias`)",
        ),
        // CRLF: the bad value on line k = 2, 3, 4.
        (
            "time_s,track,bias\r\n0,x,1\r\n1,1,1\r\n",
            "line 2, column 2 (`track`)",
        ),
        (
            "time_s,track,bias\r\n0,1,1\r\n1,1,x\r\n",
            "line 3, column 3 (`bias`)",
        ),
        (
            "time_s,track,bias\r\n0,1,1\r\n1,1,1\r\n2,x,1\r\n",
            "line 4, column 2 (`track`)",
        ),
        // A plain header and plain rows, then CRLF (the switch to the csv parser).
        (
            "time_s,track,bias\n0,1,1\n1,1,1\r\n2,1,1\r\n3,x,1\r\n",
            "line 5, column 2 (`track`)",
        ),
        // CRLF with blank CRLF lines.
        (
            "time_s,track,bias\r\n\r\n0,1,1\r\n\r\n\r\n1,1,x\r\n",
            "line 6, column 3 (`bias`)",
        ),
        // Lone CR (old Mac): each `\r` ends a line, as an editor shows it.
        (
            "time_s,track,bias\r0,1,1\r1,x,1\r",
            "line 3, column 2 (`track`)",
        ),
        (
            "# a\r\r# b\rtime_s,track,bias\r\r0,1,1\r\r1,1,x\r",
            "line 8, column 3 (`bias`)",
        ),
        // Mixed: LF rows, then lone CR, then CRLF (a plain start handing over).
        (
            "time_s,track,bias\n0,1,1\n1,1,1\r2,1,1\r\n\r3,x,1\n",
            "line 6, column 2 (`track`)",
        ),
        ("time_s,track,bias\r0,1,1\r\r1,1\r", "line 4: 2 fields"),
        // A quoted cell with an embedded newline before the bad row.
        (
            "time_s,track,bias,note\n0,1,1,\"a\nb\"\n1,x,1,c\n",
            "line 4, column 2 (`track`)",
        ),
        (
            "time_s,track,bias,note\n0,1,1,\"a\r\nb\r\nc\"\r\n1,1,x,c\r\n",
            "line 5, column 3 (`bias`)",
        ),
        // A quoted header, blank lines, then the bad row.
        (
            "\"time_s\",track,bias\n0,1,1\n\n1,1,x\n",
            "line 4, column 3 (`bias`)",
        ),
        // Metadata and blank lines before the header.
        (
            "# a\n\n# b\r\n\ntime_s,track,bias\n\n0,1,1\n\n1,x,1\n",
            "line 9, column 2 (`track`)",
        ),
        // Time backwards after blank lines.
        (
            "time_s,track,bias\n1,1,1\n\n0,1,1\n",
            "line 4, column 1 (`time_s`): time goes backwards",
        ),
        // A row of the wrong length after blank lines / in CRLF (no column: the row).
        (
            "time_s,track,bias\n0,1,1\n\n\n1,1,1,1\n",
            "line 5: 4 fields",
        ),
        (
            "\"time_s\",track,bias\r\n0,1,1\r\n1,1\r\n",
            "line 3: 2 fields",
        ),
        (
            "time_s,track,bias\r\n0,1,1\r\n\r\n1,1\r\n",
            "line 4: 2 fields",
        ),
    ];
    let map = ColumnMap::default();
    for (text, want) in cases {
        // The hand count agrees with the raw bytes: the marked row's line.
        let bad = text.find(['x', '@']).unwrap_or(text.len() - 2);
        if want.contains("column 2") || want.contains("column 3") {
            assert!(
                want.starts_with(&format!("line {}", physical_line(text.as_bytes(), bad))),
                "{text:?}: {want}"
            );
        }
        for name in ["t.csv", STDIN_NAME] {
            for (plain, fast) in [(false, false), (true, false), (true, true)] {
                for max in [1, 3, 1 << 16] {
                    let src = Pieces {
                        data: text.as_bytes(),
                        max,
                        rng: crate::numeric::rng::SimRng::new(max as u64),
                    };
                    let err = LogReader::from_reader_source(
                        name,
                        src,
                        &map,
                        BiasColumn::Required,
                        LOOKAHEAD_ROWS,
                        plain,
                    )
                    .and_then(|r| r.read_all_with(0, fast))
                    .expect_err(text)
                    .to_string();
                    let full = format!("{name}: {want}");
                    assert!(
                        err.starts_with(&full),
                        "{text:?} ({plain}, {fast}, {max}): got `{err}`, want `{full}`"
                    );
                }
                let mut r = LogReader::from_reader_source(
                    name,
                    text.as_bytes(),
                    &map,
                    BiasColumn::Required,
                    LOOKAHEAD_ROWS,
                    plain,
                )
                .unwrap();
                let err = r.summarise_each(|_| ()).expect_err(text).to_string();
                assert!(
                    err.starts_with(&format!("{name}: {want}")),
                    "summary {text:?}: `{err}`"
                );
            }
        }
    }
}

#[test]
fn lone_cr_rows_after_a_plain_start_are_not_read_whole() {
    // A log whose header and first 200 rows end in `\n` and whose 4 MiB of rows after them
    // end in a lone `\r` (no `\n`): the plain lines hand over to the csv parser at the
    // first `\r` rather than read on looking for a `\n`, row by row and in the fast rows.
    // Reference: the bytes asked of the source when the first lone-CR row comes out stay
    // within the buffers' sizes (far below 4 MiB); the rows are the ones written, on the
    // lines counted while writing them.
    struct Counted<'a>(&'a [u8], std::rc::Rc<std::cell::Cell<usize>>);
    impl Read for Counted<'_> {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            let n = self.0.len().min(buf.len());
            buf[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            self.1.set(self.1.get() + n);
            Ok(n)
        }
    }
    const PLAIN: u64 = 200;
    let mut text = String::from("time_s,track,bias\n");
    let mut rows = 0u64;
    while text.len() < 4 << 20 {
        let end = if rows < PLAIN { '\n' } else { '\r' };
        text.push_str(&format!("{rows},{},2.5{end}", rows % 1000));
        rows += 1;
    }
    for fast in [false, true] {
        let read = std::rc::Rc::new(std::cell::Cell::new(0));
        let mut r = LogReader::from_reader_source(
            "t.csv",
            Counted(text.as_bytes(), read.clone()),
            &ColumnMap::default(),
            BiasColumn::Required,
            LOOKAHEAD_ROWS,
            true,
        )
        .unwrap();
        let (mut n, mut read_at_first_cr) = (0u64, 0);
        let mut each = |row: &Row| {
            assert_eq!((row.track, row.line), ((n % 1000) as f64, n + 2), "{fast}");
            if n == PLAIN {
                read_at_first_cr = read.get();
            }
            n += 1;
        };
        if fast {
            r.summarise_each(&mut each).unwrap();
        } else {
            for row in r {
                each(&row.unwrap());
            }
        }
        assert_eq!(n, rows);
        assert!(
            read_at_first_cr < 1 << 20,
            "{fast}: {read_at_first_cr} bytes read"
        );
    }
}

#[test]
fn rows_carry_the_physical_line() {
    // Reference: the line of each row's first byte counted in the raw bytes.
    let text = "# m\r\n\r\ntime_s,track,bias,note\r\n\r\n0,1,1,\"a\r\nb\"\r\n\r\n1,2,2,c\r\n2,3,3,d\n\n3,4,4,\"\"\n";
    let log = read(text).unwrap();
    let starts: Vec<u64> = ["0,1", "1,2", "2,3", "3,4"]
        .iter()
        .map(|s| physical_line(text.as_bytes(), text.find(s).unwrap()))
        .collect();
    assert_eq!(starts, [5, 8, 9, 11]);
    let lines: Vec<u64> = (0..log.len()).map(|i| log.row(i).line).collect();
    assert_eq!(lines, starts);
}

#[test]
fn header_problems_name_the_header_line() {
    let cases: &[(&str, &str)] = &[
        (
            "# a\n\ntime_s,track,bias,track\n0,1,1,1\n",
            "t.csv: line 3: column `track` appears twice",
        ),
        (
            "# a\r\n\r\ntime_s,track\r\n0,1\r\n",
            "t.csv: line 3: missing required column `bias`",
        ),
        (
            "\n\n\"time_s\",track\n0,1\n",
            "t.csv: line 3: missing required column `bias`",
        ),
        (
            "# a\r\rtime_s,track\r0,1\r",
            "t.csv: line 3: missing required column `bias`",
        ),
        (
            "# a\r\n\rtime_s,track\r\n0,1\r\n",
            "t.csv: line 3: missing required column `bias`",
        ),
    ];
    for (text, want) in cases {
        let err = read(text).expect_err(text).to_string();
        assert!(
            err.starts_with(want),
            "{text:?}: got `{err}`, want `{want}`"
        );
    }
}

#[test]
fn a_plan_may_lack_the_bias_column_or_every_measurement() {
    // Reference: the rows as written; with BiasColumn::Optional nothing is measured and
    // no error is raised, and a covariate keeps its place.
    let read_plan = |text: &str| {
        Log::from_reader_with(
            "p.csv",
            text.as_bytes(),
            &ColumnMap::default(),
            BiasColumn::Optional,
        )
    };
    let plan = read_plan("time_s,track,temp_c\n0,100,25\n0.5,120,26\n").unwrap();
    assert!(!plan.schema.has_bias());
    assert_eq!(plan.schema.covariates, vec!["temp_c".to_string()]);
    assert_eq!(plan.row(1).covariates, vec![26.0]);
    assert_eq!(plan.measured_count(), 0);
    let empty = read_plan("time_s,track,bias\n0,100,\n0.5,120,\n").unwrap();
    assert!(empty.schema.has_bias() && empty.measured_count() == 0);
    // Other bad input is still an error naming line and column.
    let e = read_plan("time_s,track\n0,100\n0.5,x\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("p.csv: line 3, column 2 (`track`)"), "{e}");
    // Required (the default) keeps both errors.
    assert!(read("time_s,track\n0,1\n").is_err());
}

#[test]
fn byte_order_mark_before_metadata_or_header_is_skipped() {
    for text in [
        "\u{feff}# seed = 1\ntime_s,track,bias\n0,1,2\n",
        "\u{feff}time_s,track,bias\n0,1,2\n",
    ] {
        let log = read(text).expect(text);
        assert_eq!(log.row(0).bias, Some(2.0), "{text:?}");
    }
    assert_eq!(
        read("\u{feff}# seed = 1\ntime_s,track,bias\n0,1,2\n")
            .unwrap()
            .schema
            .metadata_value("seed"),
        Some("1")
    );
}

/// A source handing out `data` in pieces of 1 to `max` bytes.
struct Pieces<'a> {
    data: &'a [u8],
    max: usize,
    rng: crate::numeric::rng::SimRng,
}

impl Read for Pieces<'_> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = (1 + self.rng.below(self.max as u64) as usize)
            .min(buf.len())
            .min(self.data.len());
        buf[..n].copy_from_slice(&self.data[..n]);
        self.data = &self.data[n..];
        Ok(n)
    }
}

/// A random log text: plain rows with, now and then, a cell or line of another kind —
/// ones the reader takes (spaces, exponents, quotes, `+`, CRLF, blank lines, text in a
/// skipped column, long digit strings) and ones it refuses (text, NaN, inf, out of range,
/// time backwards, empty required cells, other field counts, bytes that are not UTF-8).
fn random_log_text(rng: &mut crate::numeric::rng::SimRng) -> Vec<u8> {
    let (header, sep, dc) = match rng.below(5) {
        0 => ("time_s,track,bias", ',', false),
        1 => ("time_s,track,bias,temp_c", ',', false),
        2 => ("time_s,track,notes,bias,temp_c", ',', false),
        3 => ("time_s;track;bias;temp_c", ';', true),
        _ => ("bias\ttime_s\ttrack", '\t', true),
    };
    let names: Vec<&str> = header.split(sep).collect();
    let mut text = format!("# seed = 1\n{header}\n").into_bytes();
    let rows = 1 + rng.below(2500);
    // Defects: rare enough that most logs read far, often enough that every kind is met.
    let odd = 0.0005 + 0.002 * rng.uniform();
    let mut t = 0.0;
    for _ in 0..rows {
        t += rng.range(0.0, 0.5);
        let mut cells: Vec<String> = names
            .iter()
            .map(|&name| match name {
                "time_s" => format!("{t:.6}"),
                "track" => format!("{}", rng.below(3000)),
                "bias" if rng.uniform() < 0.1 => String::new(),
                "bias" => format!("{:.4}", rng.range(-200.0, 200.0)),
                "temp_c" => format!("{:.2}", rng.range(20.0, 60.0)),
                _ => ["start", "", "x y", "ok"][rng.below(4) as usize].to_string(),
            })
            .collect();
        if dc {
            for c in &mut cells {
                if rng.uniform() < 0.3 {
                    *c = c.replace('.', ",");
                }
            }
        }
        let mut end = "\n";
        if rng.uniform() < odd {
            let k = rng.below(cells.len() as u64) as usize;
            let odd_cells = [
                "x",
                "NaN",
                "inf",
                "-inf",
                "1e400",
                "2e15",
                "-3e15",
                "2000000000000000",
                "-1000000000000000.5",
                " 12.5 ",
                "1e3",
                "+5",
                "\"7.5\"",
                "\"1,5\"",
                "0,5",
                "",
                "  ",
                "-",
                ".",
                "5.",
                "-0",
                ".25",
                "123456789012345678901234",
                "0.000000000000000000000000123",
                "é",
                "\u{a0}4",
                "1\"2",
                "99999999",
            ];
            match rng.below(8) {
                0 => end = ["\r\n", "\r"][rng.below(2) as usize],
                1 => end = "\n\n",
                2 => cells.push("1".into()),
                3 => {
                    cells.pop();
                }
                4 => t -= 1.0,
                5 => cells[k] = "\u{ff}".into(),
                _ => cells[k] = odd_cells[rng.below(odd_cells.len() as u64) as usize].into(),
            }
        }
        let mut line = cells.join(&sep.to_string()).into_bytes();
        if line.ends_with("\u{ff}".as_bytes()) {
            // A byte that is not UTF-8 (the cell above marks where).
            line.truncate(line.len() - 2);
            line.push(0xff);
        }
        text.extend_from_slice(&line);
        text.extend_from_slice(end.as_bytes());
    }
    if rng.uniform() < 0.2 {
        text.pop(); // no line end after the last row
    }
    text
}

#[test]
fn fast_reading_equals_the_csv_parser_and_the_row_by_row_read() {
    // Reference: every line through the csv crate's parser and every row through
    // `read_into` (the reader before the fast path). The plain lines (row by row) and the
    // fast rows must give the same log — values bit for bit, line numbers, notes — or the
    // same error word for word, whatever pieces the source hands out; and so must the
    // streaming summary (`check`'s read) and the rows it hands on.
    let mut rng = crate::numeric::rng::SimRng::new(1616);
    let map = ColumnMap::default();
    let read = |text: &[u8], plain: bool, fast: bool, max: usize, seed: u64| {
        let src = Pieces {
            data: text,
            max,
            rng: crate::numeric::rng::SimRng::new(seed),
        };
        let r = LogReader::from_reader_source(
            "t.csv",
            src,
            &map,
            BiasColumn::Required,
            LOOKAHEAD_ROWS,
            plain,
        )?;
        r.read_all_with(0, fast)
    };
    let (mut read_whole, mut errors) = (0, 0);
    for case in 0..400 {
        let text = random_log_text(&mut rng);
        let max = [1 << 16, 7, 1000][case % 3];
        let reference = read(&text, false, false, max, case as u64);
        for (plain, fast) in [(true, false), (true, true)] {
            let got = read(&text, plain, fast, max, case as u64 + 1);
            let show = || String::from_utf8_lossy(&text).into_owned();
            match (&reference, &got) {
                (Ok(a), Ok(b)) => {
                    assert!(
                        a == b,
                        "case {case} ({plain}, {fast}): logs differ\n{}",
                        show()
                    );
                    for i in 0..a.len() {
                        let bits = |l: &Log| l.bias(i).map(f64::to_bits);
                        assert_eq!(bits(a), bits(b), "case {case} row {i}");
                    }
                }
                (Err(a), Err(b)) => {
                    assert_eq!(a.to_string(), b.to_string(), "case {case}\n{}", show())
                }
                (a, b) => panic!(
                    "case {case} ({plain}, {fast}): {:?} vs {:?}\n{}",
                    a.as_ref().map(Log::len).map_err(ToString::to_string),
                    b.as_ref().map(Log::len).map_err(ToString::to_string),
                    show()
                ),
            }
        }
        // The streaming summary (`check`'s read) with the rows it hands out, the same way.
        let summarise = |plain: bool, seed: u64, rows: &mut Vec<_>| {
            let src = Pieces {
                data: &text,
                max,
                rng: crate::numeric::rng::SimRng::new(seed),
            };
            let mut r = LogReader::from_reader_source(
                "t.csv",
                src,
                &map,
                BiasColumn::Required,
                LOOKAHEAD_ROWS,
                plain,
            )?;
            let bits = |x: f64| x.to_bits();
            let summary = r.summarise_each(|row| {
                rows.push((
                    row.line,
                    bits(row.time_s),
                    bits(row.track),
                    row.bias.map(bits),
                    row.covariates.iter().map(|&c| bits(c)).collect::<Vec<_>>(),
                ))
            })?;
            Ok::<_, LogError>(summary)
        };
        let (mut rows_a, mut rows_b) = (Vec::new(), Vec::new());
        let (sa, sb) = (
            summarise(false, case as u64, &mut rows_a),
            summarise(true, case as u64 + 2, &mut rows_b),
        );
        // Line numbers against the raw bytes, the slow obvious way: the csv crate parses
        // the whole text (metadata line and header as records too) for the records'
        // bounds; a record's line is 1 + the `\n`s before its first byte, found by
        // skipping the line ends from where the parser began it.
        let delimiter = [b';', b'\t']
            .into_iter()
            .find(|d| text.split(|&b| b == b'\n').nth(1).unwrap().contains(d))
            .unwrap_or(b',');
        let mut raw = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .delimiter(delimiter)
            .from_reader(&text[..]);
        let mut record_lines = Vec::new();
        for record in raw.byte_records() {
            let Ok(record) = record else { break };
            let mut at = record.position().unwrap().byte() as usize;
            while at < text.len() && (text[at] == b'\n' || text[at] == b'\r') {
                at += 1;
            }
            record_lines.push(physical_line(&text, at));
        }
        let record_lines = &record_lines[2..]; // after `# seed = 1` and the header
        // Rows handed on before an error are the records before the bad one.
        let lines_a: Vec<u64> = rows_a.iter().map(|r| r.0).collect();
        assert_eq!(lines_a, record_lines[..lines_a.len()], "case {case}");
        if let Err(e) = &sa
            && let Some(rest) = e.to_string().split(": line ").nth(1)
        {
            let n: u64 = rest
                .split(|c: char| !c.is_ascii_digit())
                .next()
                .unwrap()
                .parse()
                .unwrap();
            assert_eq!(n, record_lines[lines_a.len()], "case {case}: {e}");
        }
        assert!(rows_a == rows_b, "case {case}: rows differ");
        match (sa, sb) {
            (Ok(a), Ok(b)) => {
                assert!(a == b, "case {case}: summaries differ");
                assert_eq!(lines_a, record_lines, "case {case}");
            }
            (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string(), "case {case}"),
            (a, b) => panic!("case {case}: {:?} vs {:?}", a.is_ok(), b.is_ok()),
        }
        match reference {
            Ok(_) => read_whole += 1,
            Err(_) => errors += 1,
        }
    }
    // Both outcomes are exercised many times.
    assert!(
        read_whole > 50 && errors > 50,
        "{read_whole} read, {errors} errors"
    );
}

#[test]
fn rows_handed_on_equal_the_row_by_row_read() {
    // Reference: `read_into` until it returns `Ok(false)` or an error, every line through the
    // csv crate's parser. `try_for_each_row` (the plain lines the fast way: predict's replay)
    // must hand on the same rows — values bit for bit, line numbers — and end with the same
    // error word for word; and a row whose handler fails ends it there, with that error.
    let mut rng = crate::numeric::rng::SimRng::new(3535);
    type Seen = (u64, u64, u64, Option<u64>, Vec<u64>);
    let seen = |row: &Row| -> Seen {
        let bits = |x: f64| x.to_bits();
        (
            row.line,
            bits(row.time_s),
            bits(row.track),
            row.bias.map(bits),
            row.covariates.iter().map(|&c| bits(c)).collect(),
        )
    };
    fn open<'a>(
        text: &'a [u8],
        plain: bool,
        max: usize,
        seed: u64,
    ) -> Result<LogReader<Pieces<'a>>, LogError> {
        let src = Pieces {
            data: text,
            max,
            rng: crate::numeric::rng::SimRng::new(seed),
        };
        LogReader::from_reader_source(
            "t.csv",
            src,
            &ColumnMap::default(),
            BiasColumn::Optional,
            LOOKAHEAD_ROWS,
            plain,
        )
    }
    let (mut whole, mut failed, mut stopped) = (0, 0, 0);
    for case in 0..400 {
        let text = random_log_text(&mut rng);
        let max = [1 << 16, 7, 1000][case % 3];
        let (mut want, mut got) = (Vec::new(), Vec::new());
        let want_end = open(&text, false, max, case as u64).and_then(|mut r| {
            let mut row = Row::empty(r.schema().covariates.len());
            while r.read_into(&mut row)? {
                want.push(seen(&row));
            }
            Ok(())
        });
        let got_end = open(&text, true, max, case as u64 + 1).and_then(|mut r| {
            r.try_for_each_row(|row| -> Result<(), LogError> {
                got.push(seen(row));
                Ok(())
            })
        });
        assert!(want == got, "case {case}: rows differ");
        match (&want_end, &got_end) {
            (Ok(()), Ok(())) => whole += 1,
            (Err(a), Err(b)) => {
                assert_eq!(a.to_string(), b.to_string(), "case {case}");
                failed += 1;
            }
            (a, b) => panic!("case {case}: {a:?} vs {b:?}"),
        }
        // A handler that fails at row `k` ends the read there, with its error.
        if want.len() > 1 {
            let k = rng.below(want.len() as u64) as usize;
            let mut n = 0;
            let end = open(&text, true, max, case as u64 + 2).and_then(|mut r| {
                r.try_for_each_row(|_| {
                    n += 1;
                    if n > k {
                        Err(LogError::NoRows {
                            file: "stop".into(),
                        })
                    } else {
                        Ok(())
                    }
                })
            });
            assert_eq!(n, k + 1, "case {case}");
            assert!(matches!(end, Err(LogError::NoRows { ref file }) if file == "stop"));
            stopped += 1;
        }
    }
    assert!(
        whole > 50 && failed > 50 && stopped > 100,
        "{whole} whole, {failed} failed, {stopped} stopped"
    );
}

#[test]
fn dialects_read_to_the_same_rows() {
    // Reference: the plain comma file; every dialect below holds the same numbers.
    let plain = read("time_s,track,bias,temp_c\n0,100,12.5,40\n0.5,120,-3.25,41\n").unwrap();
    let dialects = [
        "time_s;track;bias;temp_c\n0;100;12,5;40\n0,5;120;-3,25;41\n",
        "time_s\ttrack\tbias\ttemp_c\n0\t100\t12.5\t40\n0.5\t120\t-3.25\t41\n",
        " Time_S , TRACK ,Bias,temp_c\n0,100,12.5,40\n0.5,120,-3.25,41\n",
        "time_s,track,bias,temp_c,\n0,100,12.5,40,\n0.5,120,-3.25,41,\n",
        "time_s,track,notes,bias,temp_c\n0,100,start,12.5,40\n0.5,120,,-3.25,41\n",
    ];
    for text in dialects {
        let log = read(text).expect(text);
        assert!(
            log.rows()
                .map(|r| r.to_row())
                .eq(plain.rows().map(|r| r.to_row())),
            "{text:?}"
        );
        assert_eq!(log.schema.covariates, ["temp_c"], "{text:?}");
    }
    let notes = read(dialects[0]).unwrap().schema.notes;
    assert!(notes[0].contains("semicolon"), "{notes:?}");
    let notes = read(dialects[4]).unwrap().schema.notes;
    assert!(
        notes[0].contains("column 3 (`notes`) is not numeric (line 2: `start`); skipped"),
        "{notes:?}"
    );
    // A trailing empty column is ignored without a note; a case match is told.
    assert!(read(dialects[3]).unwrap().schema.notes.is_empty());
    assert!(read(dialects[2]).unwrap().schema.notes[0].contains("ignoring case"));
    // An explicit delimiter wins over sniffing: read as commas, `;` text is one column.
    let map = ColumnMap {
        delimiter: Some(b','),
        ..ColumnMap::default()
    };
    let e = Log::from_reader("t.csv", dialects[0].as_bytes(), &map).unwrap_err();
    assert!(
        e.to_string().contains("missing required column `time_s`"),
        "{e}"
    );
    // A numeric covariate that turns to text after the look-ahead is still an error.
    let mut late = String::from("time_s,track,bias,v\n");
    for i in 0..LOOKAHEAD_ROWS {
        late.push_str(&format!("{i},1,2,3\n"));
    }
    late.push_str("100,1,2,x\n");
    let e = read(&late).unwrap_err().to_string();
    assert!(
        e.contains(&format!(
            "line {}, column 4 (`v`): not a number",
            LOOKAHEAD_ROWS + 2
        )),
        "{e}"
    );
    // A comma file keeps the point as the only decimal separator.
    assert!(read("time_s,track,bias\n0,\"1,5\",2\n").is_err());
}

#[test]
fn a_rig_header_names_every_missing_column_and_the_flags_at_once() {
    // Reference: the header itself; each role's column is the one a reader would pick.
    let e = read("time_s,position_m,force_N,velocity_m_s\n0,1,2,3\n")
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "t.csv: line 1: missing required columns `track`, `bias` (columns found: time_s, \
         position_m, force_N, velocity_m_s); name them: ColumnMap::track position_m \
         ColumnMap::bias force_N"
    );
    // Names with spaces are quoted for the shell; a column is offered for one role only;
    // no column for a role: NAME.
    let e = read("time [s],position [um],bias [counts]\n0,1,2\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.ends_with(
            "name them: ColumnMap::time 'time [s]' ColumnMap::track 'position [um]' \
             ColumnMap::bias 'bias [counts]'"
        ),
        "{e}"
    );
    let e = read("a,b,c\n1,2,3\n").unwrap_err().to_string();
    assert!(
        e.ends_with("ColumnMap::time NAME ColumnMap::track NAME ColumnMap::bias NAME"),
        "{e}"
    );
    // One missing column keeps its own message (and a plan needs no bias column).
    let plan = Log::from_reader_with(
        "p.csv",
        "t,position_m\n0,1\n".as_bytes(),
        &ColumnMap::default(),
        BiasColumn::Optional,
    )
    .unwrap_err()
    .to_string();
    assert!(
        plan.contains("missing required columns `time_s`, `track`"),
        "{plan}"
    );
    // A header that is one column holding a delimiter: the delimiter is named.
    let e = read("time_s|track|bias\n0|1|2\n").unwrap_err().to_string();
    assert!(
        e.contains("line 1: missing required column `time_s`: the header is one column")
            && e.contains("that holds `|`"),
        "{e}"
    );
}

#[test]
fn a_unit_in_brackets_is_the_label_and_a_time_column_in_ms_is_told() {
    let map = ColumnMap {
        time: "t (ms)".into(),
        track: "position [um]".into(),
        bias: "Force (N)".into(),
        delimiter: None,
    };
    let log = Log::from_reader(
        "u.csv",
        "t (ms),position [um],Force (N)\n0,1,2\n".as_bytes(),
        &map,
    )
    .unwrap();
    assert_eq!(
        log.schema.units,
        Units {
            bias: "N".into(),
            position: "um".into()
        }
    );
    assert!(
        log.schema.notes.iter().any(|n| n
            .contains("column `t (ms)` is read in seconds, biasctl's time unit, but its name says milliseconds")),
        "{:?}",
        log.schema.notes
    );
    // Metadata and flags still win over the bracket; a name without one is its own label;
    // seconds raise no note.
    let mut schema = log.schema.clone();
    schema.set_units(Some("mN"), None).unwrap();
    assert_eq!(schema.units.bias, "mN");
    assert_eq!(unit_in_name("position_m"), None);
    assert_eq!(unit_in_name("x []"), None);
    assert_eq!(unit_in_name(" angle (rad) "), Some("rad"));
    for name in ["time_s", "time [s]", "t", "timestamp", "time_sec"] {
        assert_eq!(time_unit_not_seconds(name), None, "{name}");
    }
    for (name, unit) in [
        ("time_ms", "milliseconds"),
        ("t [us]", "microseconds"),
        ("Time (min)", "minutes"),
        ("time_h", "hours"),
    ] {
        assert_eq!(time_unit_not_seconds(name), Some(unit), "{name}");
    }
}

#[test]
fn a_header_without_rows_is_told_apart_from_rows_without_a_bias() {
    let e = read("# m\ntime_s,track,bias\n\n").unwrap_err().to_string();
    assert_eq!(
        e,
        "t.csv: no rows under the header (a log holds one row per seek)"
    );
    let e = read("time_s,track,bias\n0,1,\n").unwrap_err().to_string();
    assert_eq!(e, "t.csv: no measured rows: every `bias` cell is empty");
    // A plan may be a header alone.
    let plan = Log::from_reader_with(
        "p.csv",
        "time_s,track\n".as_bytes(),
        &ColumnMap::default(),
        BiasColumn::Optional,
    );
    assert!(plan.is_ok(), "{plan:?}");
}

#[test]
fn a_json_or_toml_file_given_as_a_log_is_named_as_such() {
    for text in [
        "{\n  \"format\": \"biasctl-model\"\n}\n",
        "# drive\n[servo]\nts_s = 1e-4\n",
    ] {
        let e = read(text).unwrap_err().to_string();
        assert!(e.contains("this is not a CSV log"), "{e}");
    }
    let e = read("# drive\n[servo]\n").unwrap_err().to_string();
    assert!(e.starts_with("t.csv: line 2:"), "{e}");
}

#[test]
fn text_that_is_not_utf8_names_its_line_and_how_to_save_it() {
    // Excel's "Unicode Text": UTF-16 with its byte-order mark.
    let utf16: Vec<u8> = "\u{feff}time_s\ttrack\tbias\r\n0\t1\t2\r\n"
        .encode_utf16()
        .flat_map(u16::to_le_bytes)
        .collect();
    let e = Log::from_reader("u.txt", &utf16[..], &ColumnMap::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("u.txt: line 1: the file is UTF-16 text"),
        "{e}"
    );
    // A Windows code page's `µ` (0xB5) in the header, after a metadata line: line 2,
    // character 24.
    let cp1252 = b"# rig 3\ntime_s,track,position [\xb5m],bias\n0,1,1,2\n";
    let e = Log::from_reader("c.csv", &cp1252[..], &ColumnMap::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("c.csv: line 2: character 24 (byte 0xB5) is not UTF-8 text"),
        "{e}"
    );
    let meta = b"# temperature in \xb0C\ntime_s,track,bias\n0,1,2\n";
    let e = Log::from_reader("m.csv", &meta[..], &ColumnMap::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("m.csv: line 1: character 18 (byte 0xB0)"),
        "{e}"
    );
}

#[test]
fn missing_column_suggests_the_closest_name() {
    let e = read("time,trk,bais\n0,1,2\n").unwrap_err().to_string();
    assert!(
        e.ends_with("name them: ColumnMap::time time ColumnMap::track trk ColumnMap::bias bais"),
        "{e}"
    );
    let e = read("time_s,trk,bias\n0,1,2\n").unwrap_err().to_string();
    assert!(
        e.contains("missing required column `track`") && e.contains("did you mean `trk`?"),
        "{e}"
    );
    // No name is close to `bias`, but `force` says it holds the role.
    let e = read("time_s,track,force\n0,1,2\n").unwrap_err().to_string();
    assert!(e.contains("did you mean `force`?"), "{e}");
    let e = read("time_s,track,note\n0,1,2\n").unwrap_err().to_string();
    assert!(!e.contains("did you mean"), "{e}");
    // A one- or two-letter name is not "in" the name looked for (`a` in `track`).
    let e = read("time_s,a,bias\n0,1,2\n").unwrap_err().to_string();
    assert!(!e.contains("did you mean"), "{e}");
    assert_eq!(sniff_delimiter("a;b,c;d"), b';');
    assert_eq!(sniff_delimiter("\"a;b\",c"), b',');
    assert_eq!(sniff_delimiter("abc"), b',');
}

/// Reference: the header names themselves. A rig's symbol-and-unit names (`t [s]`, `t_s`, `t`,
/// `F_N`, `x_mm`) are suggested for their role, and every suggested flag value is quoted for
/// the shell where it needs it; a covariate such as `T_coil` is not taken for the time.
#[test]
fn missing_columns_suggest_rig_symbols_quoted_for_the_shell() {
    let e = read(",t [s],pos_mm,F_N,T_coil\n0,0.0,1,2,20\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.ends_with(
            "name them: ColumnMap::time 't [s]' ColumnMap::track pos_mm ColumnMap::bias F_N"
        ),
        "{e}"
    );
    let e = read("T_coil,t_s,x_mm,F_N\n20,0,1,2\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.ends_with("name them: ColumnMap::time t_s ColumnMap::track x_mm ColumnMap::bias F_N"),
        "{e}"
    );
    // One column missing: the hint names the flag with the value to give it.
    let e = read("t,track,bias\n0,1,2\n").unwrap_err().to_string();
    assert!(
        e.ends_with("did you mean `t`?; name it with ColumnMap::time t"),
        "{e}"
    );
    let e = read("time (s),track,bias\n0,1,2\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.ends_with("did you mean `time (s)`?; name it with ColumnMap::time 'time (s)'"),
        "{e}"
    );
    // Neither a time in ms nor a temperature is offered as the time in seconds.
    for header in ["t_ms,track,bias", "T_coil,track,bias"] {
        let e = read(&format!("{header}\n0,1,2\n")).unwrap_err().to_string();
        assert!(!e.contains("did you mean"), "{e}");
    }
}

/// Reference: the cells as written. An empty cell in a covariate is a missing value: the whole
/// log leaves that column out with a note, a streamed row holds NaN there and the schema counts
/// the cells; an empty cell in a required column is refused without empty quotes.
#[test]
fn an_empty_covariate_cell_is_a_missing_value() {
    let text =
        "time_s,track,bias,temp_c,humidity\n0,1,2,20,50\n1,2,3,21,\n2,3,4,22,\n3,4,5,23,51\n";
    let log = read(text).unwrap();
    assert_eq!(log.len(), 4);
    assert_eq!(log.schema.covariates, ["temp_c"]);
    assert_eq!(log.covariate(0), [20.0, 21.0, 22.0, 23.0]);
    assert_eq!(log.row(1).covariates.len(), 1);
    let e = &log.schema.empty_cells[0];
    assert_eq!(
        (e.column.as_str(), e.column_index, e.count, e.first_line),
        ("humidity", 5, 2, 3)
    );
    assert!(
        log.schema.notes.iter().any(|n| n
            .starts_with("column 5 (`humidity`): 2 empty cells (line 3 first)")
            && n.contains("left out of the covariates")),
        "{:?}",
        log.schema.notes
    );
    let mut reader =
        LogReader::from_reader("t.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
    let rows: Vec<Row> = reader.by_ref().collect::<Result<_, _>>().unwrap();
    assert!(rows[1].covariates[1].is_nan() && rows[0].covariates[1] == 50.0);
    let s = reader.schema();
    assert_eq!(s.empty_cells.len(), 1);
    s.require_covariates(&rows[1], &[0]).unwrap();
    let err = s
        .require_covariates(&rows[1], &[1])
        .unwrap_err()
        .to_string();
    assert_eq!(
        err,
        "t.csv: line 3, column 5 (`humidity`): empty cell in a covariate the model reads"
    );
    let err = read("time_s,track,bias\n0,,1\n").unwrap_err().to_string();
    assert_eq!(
        err,
        "t.csv: line 2, column 2 (`track`): empty cell in a required column"
    );
}
