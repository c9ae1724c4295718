//! Recorded time series (CSV): any bytes are a series or an error naming the file; never a
//! panic. A series that reads is written back to text that reads again to the same columns and
//! the same values.
#![no_main]

use libfuzzer_sys::fuzz_target;
use vibrissa_io::series::{read_csv_str, to_csv_string};

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let Ok(series) = read_csv_str(&text, "fuzz.csv") else {
        return;
    };
    let Ok(written) = to_csv_string(&series) else {
        return;
    };
    let again = read_csv_str(&written, "written.csv").expect("a written series reads back");
    assert_eq!(again.columns, series.columns);
    for (a, b) in again.data.iter().zip(&series.data) {
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(b) {
            assert!(x == y || (x.is_nan() && y.is_nan()), "{x} read back as {y}");
        }
    }
});
