//! Time series: CSV round trips and errors, NPY and NPZ bytes, sidecars, and what numpy, pandas
//! and polars read back.

use std::fs;
use std::path::PathBuf;
use vibrissa_core::sim::COLUMNS;
use vibrissa_io::series::{
    merge_sidecar, read_csv, read_csv_str, read_csv_with_sidecar, sidecar_path, to_csv_string,
    write, write_csv, write_npy, write_npz, Series, SidecarWarning,
};
use vibrissa_io::Error;

/// A fresh folder for this test's files.
fn temp_dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("series-{name}"));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

/// A run-like series in the contract's columns with awkward values.
fn sample() -> Series {
    let mut s = Series::new(&COLUMNS);
    s.set_meta("segments", 20);
    s.set_meta("scenario", "e2 (d = 0.023)");
    let awkward = [
        0.1,
        -0.0,
        1.0 / 3.0,
        1e-7,
        -2.5e-12,
        6.02214076e23,
        f64::MIN_POSITIVE,
        5e-324,
        f64::MAX,
        123456.789,
    ];
    for r in 0..7 {
        let row: Vec<f64> = (0..COLUMNS.len())
            .map(|c| match (r, c) {
                (_, 0) => r as f64 * 1e-3,
                (3, 7..=9) => f64::NAN,
                _ => awkward[(r + c) % awkward.len()] * if c % 2 == 0 { 1.0 } else { -1.0 },
            })
            .collect();
        s.push_row(&row);
    }
    s
}

/// Same columns, metadata and bits (NaN equal to NaN).
fn assert_same(a: &Series, b: &Series) {
    assert_eq!(a.columns, b.columns);
    assert_eq!(a.meta, b.meta);
    for (x, y) in a.data.iter().zip(&b.data) {
        let xb: Vec<u64> = x.iter().map(|v| v.to_bits()).collect();
        let yb: Vec<u64> = y.iter().map(|v| v.to_bits()).collect();
        assert_eq!(xb.len(), yb.len());
        for (p, q) in xb.iter().zip(&yb) {
            let (p, q) = (f64::from_bits(*p), f64::from_bits(*q));
            assert!(
                p.to_bits() == q.to_bits() || (p.is_nan() && q.is_nan()),
                "{p} != {q}"
            );
        }
    }
}

#[test]
fn csv_round_trip_is_exact() {
    let dir = temp_dir("round-trip");
    let path = dir.join("run.csv");
    let s = sample();
    write(&s, &path).unwrap();

    // The CSV alone has the data; its sidecar adds the metadata.
    let alone = read_csv(&path).unwrap();
    assert!(alone.meta.is_empty(), "{:?}", alone.meta);
    let (back, warnings) = read_csv_with_sidecar(&path).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_same(&s, &back);
    assert_eq!(back.meta_value("segments"), Some("20"));
    assert_eq!(back.rows(), 7);

    // The layout the contract describes: the header first, no comment lines.
    let text = fs::read_to_string(&path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], COLUMNS.join(","));
    assert_eq!(lines.len(), 8);
    assert!(lines[1].starts_with("0.0,"), "{}", lines[1]);
    assert!(lines[4].ends_with("NaN,NaN,NaN"), "{}", lines[4]);
    assert!(!text.contains('#') && !text.contains("inf"));
    assert_eq!(to_csv_string(&s).unwrap(), text);
    // Every value is a floating-point literal, so no reader takes a column for integers.
    for line in &lines[1..] {
        for cell in line.split(',') {
            assert!(
                cell == "NaN" || cell.contains(['.', 'e']),
                "{cell:?} in {line:?}"
            );
        }
    }

    // The sidecar: the file it describes, its rows and columns, the metadata in order.
    assert_eq!(sidecar_path(&path), dir.join("run.json"));
    let json = fs::read_to_string(dir.join("run.json")).unwrap();
    assert!(json.contains("\"file\": \"run.csv\""), "{json}");
    assert!(json.contains("\"rows\": 7"), "{json}");
    assert!(json.contains("\"segments\": \"20\""), "{json}");
    assert!(
        json.find("segments").unwrap() < json.find("scenario").unwrap(),
        "{json}"
    );

    // Nothing else is left in the folder.
    assert_eq!(fs::read_dir(&dir).unwrap().count(), 2);
}

#[test]
fn csv_reader_skips_comments_and_blank_lines() {
    let text = "\u{feff}# written by hand\r\n\r\n# segments = 10\r\nt, theta01 ,theta12\r\n0,0.1,NaN\r\n# a note = between rows\r\n\r\n1e-3,-2E-1,nan\r\n";
    let s = read_csv_str(text, "hand.csv").unwrap();
    assert_eq!(s.columns, ["t", "theta01", "theta12"]);
    assert_eq!(s.column("t").unwrap(), [0.0, 1e-3]);
    assert_eq!(s.column("theta01").unwrap(), [0.1, -0.2]);
    assert!(s.column("theta12").unwrap().iter().all(|x| x.is_nan()));
    // `# key = value` with a key of letters, digits, `_`, `-`, `.` is metadata; other comments are not.
    assert_eq!(s.meta, [("segments".to_string(), "10".to_string())]);
    assert!(s.column("m0").is_none());
}

#[test]
fn require_lists_missing_and_present_columns() {
    let s = read_csv_str("t,theta01,m0\n0,1,2\n", "x.csv").unwrap();
    let cols = s.require(&["t", "theta01"]).unwrap();
    assert_eq!(cols, [&[0.0][..], &[1.0][..]]);
    let e = s.require(&["t", "theta01", "theta12", "fy"]).unwrap_err();
    assert!(matches!(&e, Error::MissingColumns { missing, .. } if missing == &["theta12", "fy"]));
    let e = e.to_string();
    assert!(
        e.contains("theta12, fy") && e.contains("t, theta01, m0"),
        "{e}"
    );
}

#[test]
fn csv_errors_name_file_line_and_column() {
    let cases = [
        (
            "t,theta01\n0,0.1\n1,abc\n",
            "line 3",
            "`theta01`: `abc` is not a number",
        ),
        (
            "t,theta01\n0,0.1\n1,inf\n",
            "line 3",
            "`theta01`: `inf` is not finite",
        ),
        ("t,theta01\n0,-infinity\n", "line 2", "not finite"),
        ("t,theta01\n0,\n", "line 2", "`theta01`: the cell is empty"),
        (
            "t,theta01\n0,0.1\n1,0.2,0.3\n",
            "line 3",
            "3 values, but the header has 2 columns",
        ),
        ("t,theta01\n0\n", "line 2", "1 values"),
        ("t,t\n0,0\n", "line 1", "`t` appears twice"),
        ("t,,x\n", "line 1", "column 2"),
        // A byte-order mark that is not the file's first character, or a control character,
        // cannot be written back as a header (found by fuzzing the reader).
        ("\n\u{feff}#\n", "line 2", "byte-order marks"),
        ("t,a\u{7}b\n", "line 1", "column 2 of the header"),
    ];
    for (text, a, b) in cases {
        let e = read_csv_str(text, "obs.csv").unwrap_err().to_string();
        assert!(
            e.starts_with("obs.csv, ") && e.contains(a) && e.contains(b),
            "{text:?}: {e}"
        );
    }
    // Cells are trimmed, quoted or not: a quoted name's spaces go too.
    let s = read_csv_str("t,\" a\"\n", "obs.csv").unwrap();
    assert_eq!(s.columns, ["t", "a"]);
    // Lines are counted across blank lines and comments.
    let e = read_csv_str("\n# a = 1\n\nt,x\n\n0,zz\n", "obs.csv")
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 6") && e.contains("`zz`"), "{e}");
    // A file wrong as a whole names no line.
    for text in ["", "# only a comment\n\n"] {
        let e = read_csv_str(text, "obs.csv").unwrap_err().to_string();
        assert!(
            e.starts_with("obs.csv: ") && e.contains("no header row") && !e.contains("line"),
            "{text:?}: {e}"
        );
    }
    // From a file: the path is named; a missing file too.
    let dir = temp_dir("csv-errors");
    let path = dir.join("ragged.csv");
    fs::write(&path, "t,a\n0,1\n1\n").unwrap();
    let e = read_csv(&path).unwrap_err().to_string();
    assert!(e.contains("ragged.csv, line 3"), "{e}");
    let e = read_csv(dir.join("none.csv")).unwrap_err().to_string();
    assert!(e.contains("cannot read") && e.contains("none.csv"), "{e}");
}

#[test]
fn a_file_separated_by_semicolons_or_tabs_is_named_so() {
    for (sep, shown) in [(";", "';'"), ("\t", "'\\t'")] {
        let text = format!("t{sep}theta01{sep}theta12\n0{sep}0.1{sep}0.2\n");
        let e = read_csv_str(&text, "sep.csv").unwrap_err().to_string();
        assert!(
            e.contains("sep.csv, line 1") && e.contains(&format!("separated by {shown}")),
            "{e}"
        );
    }
    // A one-column file is still a file of one column.
    assert_eq!(read_csv_str("t\n0\n1\n", "t.csv").unwrap().rows(), 2);
}

#[test]
fn header_only_csv_has_no_rows() {
    let s = read_csv_str("t,theta01,theta12\n", "h.csv").unwrap();
    assert_eq!(s.rows(), 0);
    assert_eq!(s.require(&["t", "theta01", "theta12"]).unwrap()[2].len(), 0);
}

#[test]
fn failed_writes_leave_old_files_alone() {
    let dir = temp_dir("atomic");
    let mut bad = Series::new(&["t", "x"]);
    bad.push_row(&[0.0, 1.0]);
    bad.push_row(&[1.0, f64::INFINITY]);
    for name in ["out.csv", "out.npy", "out.npz"] {
        let path = dir.join(name);
        fs::write(&path, "old").unwrap();
        let e = write(&bad, &path).unwrap_err().to_string();
        assert!(e.contains("`x`") && e.contains("row 1"), "{e}");
        assert_eq!(fs::read_to_string(&path).unwrap(), "old");
    }
    // Other invalid series: ragged, duplicate or unwritable names, bad metadata.
    let mut ragged = Series::new(&["t", "x"]);
    ragged.data[0].push(0.0);
    let mut dup = Series::new(&["t", "t"]);
    dup.push_row(&[0.0, 0.0]);
    let comma = Series::new(&["a,b"]);
    let mut meta = Series::new(&["t"]);
    meta.set_meta("two\nlines", 1);
    for s in [ragged, dup, comma, meta] {
        assert!(matches!(
            write_csv(&s, dir.join("out.csv")),
            Err(Error::InvalidSeries(_))
        ));
    }
    assert!(matches!(
        write_npz(&Series::new(&["a/b"]), dir.join("out.npz")),
        Err(Error::InvalidSeries(_))
    ));
    // A folder that does not exist.
    let e = write_csv(&sample(), dir.join("no/such/dir/out.csv")).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e}");
    let e = write(&sample(), dir.join("no/such/dir/out.csv")).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e}");
    // Only the three old files remain: no temporary files, no sidecar.
    assert_eq!(fs::read_dir(&dir).unwrap().count(), 3);

    // The data file cannot take its place (a folder is in the way): the sidecar, already
    // renamed, is removed again, and no temporary file is left.
    fs::create_dir(dir.join("busy.csv")).unwrap();
    fs::write(dir.join("busy.csv/keep"), "").unwrap();
    let e = write(&sample(), dir.join("busy.csv")).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e}");
    assert!(!dir.join("busy.json").exists());
    // A folder where the sidecar goes: nothing is written either.
    fs::create_dir(dir.join("side.json")).unwrap();
    let e = write(&sample(), dir.join("side.csv")).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e}");
    assert!(!dir.join("side.csv").exists());
    assert_eq!(fs::read_dir(&dir).unwrap().count(), 5);
}

#[test]
fn format_follows_the_extension() {
    let dir = temp_dir("extension");
    let s = sample();
    write(&s, dir.join("a.csv")).unwrap();
    write(&s, dir.join("b.NPY")).unwrap();
    write(&s, dir.join("c.npz")).unwrap();
    assert!(fs::read(dir.join("a.csv"))
        .unwrap()
        .starts_with(b"t,theta01,"));
    assert!(fs::read(dir.join("b.NPY"))
        .unwrap()
        .starts_with(b"\x93NUMPY"));
    assert!(fs::read(dir.join("c.npz"))
        .unwrap()
        .starts_with(b"PK\x03\x04"));
    // Each with its sidecar, naming it.
    for (data, side) in [
        ("a.csv", "a.json"),
        ("b.NPY", "b.json"),
        ("c.npz", "c.json"),
    ] {
        let json = fs::read_to_string(dir.join(side)).unwrap();
        assert!(json.contains(&format!("\"file\": \"{data}\"")), "{json}");
    }
    for bad in ["a.txt", "a", "a.csv.gz"] {
        let e = write(&s, dir.join(bad)).unwrap_err();
        assert!(matches!(e, Error::Format { .. }));
        let e = e.to_string();
        assert!(e.contains(".csv, .npy, .npz"), "{e}");
    }
}

/// Parses an NPY header, checking its layout: the shape and where the data starts.
fn parse_npy_header(bytes: &[u8]) -> (Vec<usize>, usize) {
    assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00", "magic and version 1.0");
    let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let data_start = 10 + header_len;
    assert_eq!(data_start % 64, 0, "data aligned to 64 bytes");
    let header = std::str::from_utf8(&bytes[10..data_start]).unwrap();
    assert!(header.ends_with('\n'));
    let dict = header.trim_end_matches('\n').trim_end_matches(' ');
    // A Python dict literal with exactly numpy's three keys.
    assert!(
        dict.starts_with("{'descr': '<f8', 'fortran_order': False, 'shape': ("),
        "{dict}"
    );
    assert!(dict.ends_with("), }"), "{dict}");
    let inner = &dict[dict.find("'shape': (").unwrap() + 10..dict.len() - 4];
    let shape = inner
        .split(',')
        .map(str::trim)
        .filter(|p| !p.is_empty())
        .map(|p| p.parse().unwrap())
        .collect();
    (shape, data_start)
}

/// Parses an NPY file: shape and float64 values.
fn parse_npy(bytes: &[u8]) -> (Vec<usize>, Vec<f64>) {
    let (shape, data_start) = parse_npy_header(bytes);
    assert_eq!((bytes.len() - data_start) % 8, 0);
    let values: Vec<f64> = bytes[data_start..]
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert_eq!(values.len(), shape.iter().product::<usize>());
    (shape, values)
}

fn same_bits(a: f64, b: f64) -> bool {
    a.to_bits() == b.to_bits()
}

#[test]
fn npy_holds_rows_by_columns_in_c_order() {
    let dir = temp_dir("npy");
    let s = sample();
    let path = dir.join("run.npy");
    write_npy(&s, &path).unwrap();
    let (shape, values) = parse_npy(&fs::read(&path).unwrap());
    assert_eq!(shape, [s.rows(), s.columns.len()]);
    for r in 0..s.rows() {
        for c in 0..s.columns.len() {
            assert!(same_bits(values[r * s.columns.len() + c], s.data[c][r]));
        }
    }
    // Header padding for a range of shapes, one-dimensional ones included.
    for (shape, text) in [
        (vec![0, 0], "(0, 0)"),
        (vec![151, 10], "(151, 10)"),
        (vec![123456789, 12], "(123456789, 12)"),
        (vec![5], "(5,)"),
    ] {
        let h = vibrissa_io::series::npy_header(&shape);
        assert_eq!(h.len() % 64, 0);
        assert!(String::from_utf8_lossy(&h).contains(text));
        assert_eq!(parse_npy_header(&h), (shape, h.len()));
    }
    // An empty series is a valid (0, C) array.
    write_npy(&Series::new(&COLUMNS), &path).unwrap();
    assert_eq!(parse_npy(&fs::read(&path).unwrap()).0, [0, COLUMNS.len()]);
}

fn u16_at(b: &[u8], i: usize) -> usize {
    u16::from_le_bytes([b[i], b[i + 1]]) as usize
}

fn u32_at(b: &[u8], i: usize) -> u32 {
    u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]])
}

/// Reads a stored ZIP archive through its central directory: (name, data) per entry, checking
/// signatures, sizes and CRCs.
fn parse_zip(b: &[u8]) -> Vec<(String, Vec<u8>)> {
    // End of central directory record: the last 22 bytes (no comment).
    let eocd = b.len() - 22;
    assert_eq!(
        u32_at(b, eocd),
        0x0605_4b50,
        "end of central directory signature"
    );
    let entries = u16_at(b, eocd + 10);
    assert_eq!(entries, u16_at(b, eocd + 8));
    let cd_size = u32_at(b, eocd + 12) as usize;
    let cd_start = u32_at(b, eocd + 16) as usize;
    assert_eq!(cd_start + cd_size, eocd);

    let mut out = Vec::new();
    let mut p = cd_start;
    for _ in 0..entries {
        assert_eq!(u32_at(b, p), 0x0201_4b50, "central directory header");
        assert_eq!(u16_at(b, p + 10), 0, "stored");
        let crc = u32_at(b, p + 16);
        let (csize, usize_) = (u32_at(b, p + 20) as usize, u32_at(b, p + 24) as usize);
        assert_eq!(csize, usize_);
        let name_len = u16_at(b, p + 28);
        let extra = u16_at(b, p + 30) + u16_at(b, p + 32);
        let local = u32_at(b, p + 42) as usize;
        let name = String::from_utf8(b[p + 46..p + 46 + name_len].to_vec()).unwrap();

        // The local header agrees, and the data's CRC matches.
        assert_eq!(u32_at(b, local), 0x0403_4b50, "local file header");
        assert_eq!(u32_at(b, local + 14), crc);
        assert_eq!(u32_at(b, local + 18) as usize, csize);
        let local_name_len = u16_at(b, local + 26);
        let data_start = local + 30 + local_name_len + u16_at(b, local + 28);
        assert_eq!(&b[local + 30..local + 30 + local_name_len], name.as_bytes());
        let data = b[data_start..data_start + csize].to_vec();
        assert_eq!(crc32fast::hash(&data), crc, "{name}");
        out.push((name, data));
        p += 46 + name_len + extra;
    }
    assert_eq!(p, eocd);
    out
}

#[test]
fn npz_is_a_zip_of_one_npy_per_column() {
    let dir = temp_dir("npz");
    let s = sample();
    let path = dir.join("run.npz");
    write_npz(&s, &path).unwrap();
    let bytes = fs::read(&path).unwrap();
    let entries = parse_zip(&bytes);
    let names: Vec<&str> = entries.iter().map(|(n, _)| n.as_str()).collect();
    let expected: Vec<String> = COLUMNS.iter().map(|c| format!("{c}.npy")).collect();
    assert_eq!(names, expected);
    for ((_, data), col) in entries.iter().zip(&s.data) {
        let (shape, values) = parse_npy(data);
        assert_eq!(shape, [s.rows()]);
        assert!(values.iter().zip(col).all(|(a, b)| same_bits(*a, *b)));
    }
    // The same data gives the same bytes.
    write_npz(&s, dir.join("again.npz")).unwrap();
    assert_eq!(fs::read(dir.join("again.npz")).unwrap(), bytes);
}

/// Writes `sample()` to `dir/name` with its sidecar, then replaces the sidecar's text.
fn with_sidecar(dir: &std::path::Path, name: &str, sidecar: &str) -> PathBuf {
    let path = dir.join(name);
    write(&sample(), &path).unwrap();
    fs::write(sidecar_path(&path), sidecar).unwrap();
    path
}

#[test]
fn a_missing_sidecar_is_no_problem() {
    let dir = temp_dir("sidecar-missing");
    let path = dir.join("run.csv");
    write_csv(&sample(), &path).unwrap();
    assert!(
        !dir.join("run.json").exists(),
        "write_csv writes the CSV alone"
    );
    let (s, warnings) = read_csv_with_sidecar(&path).unwrap();
    assert!(warnings.is_empty() && s.meta.is_empty(), "{warnings:?}");
    assert_eq!(s.rows(), 7);
}

#[test]
fn bad_sidecars_are_warnings_and_the_csv_is_read_all_the_same() {
    let dir = temp_dir("sidecar-bad");
    let cols = format!("{:?}", COLUMNS).replace(' ', "");
    let cases = [
        (
            "not-json.csv",
            "{\"meta\": ".to_string(),
            "is not a valid sidecar",
        ),
        ("array.csv", "[]".to_string(), "is not a valid sidecar"),
        ("empty.csv", String::new(), "the file is empty"),
        (
            "estimate.csv",
            "{\n  \"d\": {\"mean\": 0.02},\n  \"method\": \"pf\"\n}\n".to_string(),
            "it holds an estimate, not a sidecar",
        ),
        (
            "estimates.csv",
            "{\"file\": \"a.csv\", \"method\": \"krr\"}\n{\"file\": \"b.csv\", \"method\": \"krr\"}\n"
                .to_string(),
            "it holds an estimate, not a sidecar",
        ),
        (
            "bad-key.csv",
            "{\"meta\": {\"two words\": \"x\"}}".to_string(),
            "metadata key \"two words\"",
        ),
        (
            "rows.csv",
            format!("{{\"rows\": 8, \"columns\": {cols}, \"meta\": {{\"segments\": \"5\"}}}}"),
            "it records 8 rows, the file has 7",
        ),
        (
            "columns.csv",
            "{\"rows\": 7, \"columns\": [\"t\"], \"meta\": {\"segments\": \"5\"}}".to_string(),
            "it lists the columns t, the file has t,theta01",
        ),
        (
            "format.csv",
            "{\"file\": \"format.npz\", \"meta\": {\"segments\": \"5\"}}".to_string(),
            "it describes `format.npz`",
        ),
    ];
    for (name, sidecar, says) in cases {
        let path = with_sidecar(&dir, name, &sidecar);
        let (s, warnings) = read_csv_with_sidecar(&path).unwrap();
        assert_eq!(warnings.len(), 1, "{name}: {warnings:?}");
        let w = warnings[0].to_string();
        assert!(w.contains(says), "{name}: {w}");
        assert!(w.contains("its metadata is ignored"), "{name}: {w}");
        // The data is all there; none of the sidecar's metadata is.
        assert_eq!(s.rows(), 7);
        assert!(s.meta.is_empty(), "{name}: {:?}", s.meta);
    }

    // A sidecar renamed together with its data still matches.
    let path = with_sidecar(
        &dir,
        "renamed.csv",
        &format!("{{\"file\": \"run.CSV\", \"rows\": 7, \"columns\": {cols}, \"meta\": {{\"segments\": 5}}}}"),
    );
    let (s, warnings) = read_csv_with_sidecar(&path).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(s.meta_value("segments"), Some("5"));

    // A sidecar that cannot be read: a folder in its place.
    let path = dir.join("folder.csv");
    write_csv(&sample(), &path).unwrap();
    fs::create_dir(dir.join("folder.json")).unwrap();
    let (s, warnings) = read_csv_with_sidecar(&path).unwrap();
    assert!(
        matches!(&warnings[..], [SidecarWarning::Unreadable { .. }]),
        "{warnings:?}"
    );
    assert_eq!(s.rows(), 7);

    // A bad CSV is still an error, whatever its sidecar.
    let bad = dir.join("bad.csv");
    fs::write(&bad, "t,x\n0\n").unwrap();
    fs::write(dir.join("bad.json"), "{\"meta\": {}}").unwrap();
    assert!(read_csv_with_sidecar(&bad).is_err());
}

#[test]
fn a_csvs_own_comment_lines_win_over_its_sidecar() {
    let dir = temp_dir("sidecar-conflict");
    let path = dir.join("old.csv");
    fs::write(&path, "# segments = 20\n# note = kept\nt,x\n0,1\n").unwrap();
    fs::write(
        dir.join("old.json"),
        "{\"meta\": {\"segments\": \"10\", \"note\": \"kept\", \"dt\": \"0.0001\"}}",
    )
    .unwrap();
    let (s, warnings) = read_csv_with_sidecar(&path).unwrap();
    let texts: Vec<String> = warnings.iter().map(ToString::to_string).collect();
    assert_eq!(texts.len(), 1, "{texts:?}");
    assert!(
        texts[0].contains("segments = \"10\"") && texts[0].contains("segments = \"20\""),
        "{}",
        texts[0]
    );
    let expect = [("segments", "20"), ("note", "kept"), ("dt", "0.0001")];
    let meta: Vec<(&str, &str)> = s
        .meta
        .iter()
        .map(|(k, v)| (k.as_str(), v.as_str()))
        .collect();
    assert_eq!(meta, expect);

    // merge_sidecar serves series read some other way too.
    let mut other = Series::new(&["t", "x"]);
    other.push_row(&[0.0, 1.0]);
    assert!(merge_sidecar(&mut other, &path).is_empty());
    assert_eq!(other.meta_value("segments"), Some("10"));
}

/// Whether `python3` with numpy runs here.
fn numpy_available() -> bool {
    std::process::Command::new("python3")
        .args(["-c", "import numpy"])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// What the Python readers are asked to read: the awkward sample, a column whose first 150
/// values are whole numbers (a reader that guesses types from the first rows must still take it
/// as floating point), and values with every kind of bit pattern.
fn interop_series() -> Series {
    let s = sample();
    let mut out = Series::new(&s.columns);
    out.meta = s.meta.clone();
    let mut bits = 0x9E37_79B9_7F4A_7C15u64;
    for r in 0..400 {
        let row: Vec<f64> = (0..s.columns.len())
            .map(|c| {
                if c == 3 {
                    return if r < 150 {
                        (r % 3) as f64
                    } else {
                        r as f64 / 7.0
                    };
                }
                if r < s.rows() {
                    return s.data[c][r];
                }
                if c == 0 {
                    return r as f64 * 1e-3;
                }
                // A finite value from a scrambled bit pattern (xorshift).
                loop {
                    bits ^= bits << 13;
                    bits ^= bits >> 7;
                    bits ^= bits << 17;
                    let x = f64::from_bits(bits);
                    if x.is_finite() {
                        return x;
                    }
                }
            })
            .collect();
        out.push_row(&row);
    }
    out
}

#[test]
fn numpy_reads_what_is_written_when_available() {
    if !numpy_available() {
        // CI sets this: there the test must run.
        assert!(
            std::env::var_os("VIBRISSA_REQUIRE_INTEROP").is_none(),
            "VIBRISSA_REQUIRE_INTEROP is set, but python3 cannot import numpy"
        );
        eprintln!("numpy_reads_what_is_written_when_available: skipped (no python3 with numpy)");
        return;
    }
    let dir = temp_dir("numpy");
    let s = interop_series();
    let (npy, npz, csv) = (dir.join("r.npy"), dir.join("r.npz"), dir.join("r.csv"));
    write(&s, &npy).unwrap();
    write(&s, &npz).unwrap();
    write(&s, &csv).unwrap();

    // Each reader with its defaults; every value comes back as its 64 bits in hexadecimal, one
    // line per reader and column: `reader column bits bits ...`.
    let script = r##"
import importlib.util, json, struct, sys
import numpy as np
npy, npz, csv, sidecar = sys.argv[1:5]
def show(reader, name, values):
    bits = [struct.pack(">d", float(x)).hex() for x in values]
    print(reader, name, " ".join(bits))
a = np.load(npy)
assert a.dtype == np.float64, a.dtype
names = json.load(open(sidecar))["columns"]
assert a.ndim == 2 and a.shape[1] == len(names), a.shape
for k, name in enumerate(names):
    show("npy", name, a[:, k])
with np.load(npz) as z:
    for entry in z.files:
        show("npz", entry, z[entry])
g = np.genfromtxt(csv, delimiter=",", names=True)
for name in g.dtype.names:
    assert g[name].dtype == np.float64, (name, g[name].dtype)
    show("genfromtxt", name, g[name])
l = np.loadtxt(csv, delimiter=",", skiprows=1)
assert l.dtype == np.float64
for k, name in enumerate(names):
    show("loadtxt", name, l[:, k])
if importlib.util.find_spec("pandas"):
    import pandas as pd
    p = pd.read_csv(csv)
    for name in p.columns:
        assert p[name].dtype == np.float64, (name, p[name].dtype)
        show("pandas", name, p[name].to_numpy())
else:
    print("missing pandas")
if importlib.util.find_spec("polars"):
    import polars as pl
    q = pl.read_csv(csv)
    for name in q.columns:
        assert q[name].dtype == pl.Float64, (name, q[name].dtype)
        show("polars", name, q[name].to_list())
else:
    print("missing polars")
"##;
    let out = std::process::Command::new("python3")
        .args(["-c", script])
        .args([&npy, &npz, &csv, &dir.join("r.json")].map(|p: &PathBuf| p.as_os_str().to_owned()))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}\n{stdout}",
        String::from_utf8_lossy(&out.stderr)
    );

    // Every reader gave every column, with every value's bits (any NaN for a NaN).
    let mut readers = vec!["npy", "npz", "genfromtxt", "loadtxt", "pandas", "polars"];
    let mut seen: Vec<(String, String)> = Vec::new();
    for line in stdout.lines() {
        let mut parts = line.split(' ');
        let (reader, name) = (parts.next().unwrap(), parts.next().unwrap_or(""));
        if reader == "missing" {
            assert!(
                name != "pandas" || std::env::var_os("VIBRISSA_REQUIRE_INTEROP").is_none(),
                "VIBRISSA_REQUIRE_INTEROP is set, but python3 cannot import pandas"
            );
            eprintln!(
                "numpy_reads_what_is_written_when_available: {name} not checked (not installed)"
            );
            readers.retain(|r| *r != name);
            continue;
        }
        let column = name.strip_suffix(".npy").unwrap_or(name);
        let expected = s
            .column(column)
            .unwrap_or_else(|| panic!("{reader}: unknown column {name}"));
        let got: Vec<f64> = parts
            .map(|h| f64::from_bits(u64::from_str_radix(h, 16).unwrap()))
            .collect();
        assert_eq!(got.len(), expected.len(), "{reader} {name}");
        for (row, (g, e)) in got.iter().zip(expected).enumerate() {
            assert!(
                g.to_bits() == e.to_bits() || (g.is_nan() && e.is_nan()),
                "{reader} {name} row {row}: read {g:e} ({:#x}), wrote {e:e} ({:#x})",
                g.to_bits(),
                e.to_bits()
            );
        }
        seen.push((reader.to_string(), column.to_string()));
    }
    for reader in readers {
        for column in &s.columns {
            assert!(
                seen.contains(&(reader.to_string(), column.clone())),
                "{reader} did not give column {column}"
            );
        }
    }
    eprintln!(
        "numpy_reads_what_is_written_when_available: {} columns of {} rows checked bit for bit",
        seen.len(),
        s.rows()
    );
}
