//! A minimal ZIP writer (stored entries only) and CRC-32.

use std::io::{self, Write};

/// CRC-32 lookup table (IEEE 802.3, reflected polynomial `0xEDB88320`), one entry per byte.
const CRC_TABLE: [u32; 256] = crc_table();

const fn crc_table() -> [u32; 256] {
    let mut table = [0u32; 256];
    let mut n = 0;
    while n < 256 {
        let mut c = n as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
            k += 1;
        }
        table[n] = c;
        n += 1;
    }
    table
}

/// CRC-32 of `data` as ZIP, gzip and PNG use it (`crc32(b"123456789") == 0xCBF43926`).
pub fn crc32(data: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in data {
        c = CRC_TABLE[((c ^ b as u32) & 0xFF) as usize] ^ (c >> 8);
    }
    !c
}

/// Signatures of the three ZIP records written.
const LOCAL_HEADER: u32 = 0x0403_4b50;
const CENTRAL_HEADER: u32 = 0x0201_4b50;
const END_OF_CENTRAL_DIRECTORY: u32 = 0x0605_4b50;

/// "Version needed to extract": 2.0, the baseline every reader supports.
const VERSION: u16 = 20;

/// MS-DOS date of 1980-01-01 (the format's epoch); the time field is midnight. A fixed date makes
/// archives of the same data byte-identical.
const DOS_DATE: u16 = (1 << 5) | 1;

/// One entry already written, as the central directory lists it.
struct Entry {
    name: Vec<u8>,
    flags: u16,
    crc: u32,
    size: u32,
    offset: u32,
}

/// Writes a ZIP archive of uncompressed ("stored") entries. Archives and entries are limited to
/// 4 GiB and 65 535 entries (no ZIP64).
pub(crate) struct ZipWriter<W: Write> {
    out: W,
    offset: u64,
    entries: Vec<Entry>,
}

impl<W: Write> ZipWriter<W> {
    /// Starts an archive on `out`.
    pub(crate) fn new(out: W) -> Self {
        ZipWriter {
            out,
            offset: 0,
            entries: Vec::new(),
        }
    }

    /// Appends one stored entry.
    pub(crate) fn add(&mut self, name: &str, data: &[u8]) -> io::Result<()> {
        let too_big =
            || io::Error::other("archive over 4 GiB or 65 535 entries (ZIP64 is not supported)");
        if self.entries.len() >= u16::MAX as usize {
            return Err(too_big());
        }
        let size = u32::try_from(data.len()).map_err(|_| too_big())?;
        let offset = u32::try_from(self.offset).map_err(|_| too_big())?;
        let name_len =
            u16::try_from(name.len()).map_err(|_| io::Error::other("entry name too long"))?;
        // Bit 11: the name is UTF-8.
        let flags = if name.is_ascii() { 0 } else { 1 << 11 };
        let crc = crc32(data);

        // Local file header, name, data.
        let mut h = Vec::with_capacity(30 + name.len());
        put32(&mut h, LOCAL_HEADER);
        put16(&mut h, VERSION);
        put16(&mut h, flags);
        put16(&mut h, 0); // method: stored
        put16(&mut h, 0); // time
        put16(&mut h, DOS_DATE);
        put32(&mut h, crc);
        put32(&mut h, size); // compressed size
        put32(&mut h, size); // uncompressed size
        put16(&mut h, name_len);
        put16(&mut h, 0); // extra field length
        h.extend_from_slice(name.as_bytes());
        self.out.write_all(&h)?;
        self.out.write_all(data)?;
        self.offset += (h.len() + data.len()) as u64;

        self.entries.push(Entry {
            name: name.as_bytes().to_vec(),
            flags,
            crc,
            size,
            offset,
        });
        Ok(())
    }

    /// Writes the central directory and the end record; returns the output.
    pub(crate) fn finish(mut self) -> io::Result<W> {
        let too_big = || io::Error::other("archive over 4 GiB (ZIP64 is not supported)");
        let start = u32::try_from(self.offset).map_err(|_| too_big())?;

        // Central directory: one header per entry.
        let mut cd = Vec::new();
        for e in &self.entries {
            put32(&mut cd, CENTRAL_HEADER);
            put16(&mut cd, VERSION); // version made by
            put16(&mut cd, VERSION); // version needed
            put16(&mut cd, e.flags);
            put16(&mut cd, 0); // method: stored
            put16(&mut cd, 0); // time
            put16(&mut cd, DOS_DATE);
            put32(&mut cd, e.crc);
            put32(&mut cd, e.size);
            put32(&mut cd, e.size);
            put16(&mut cd, e.name.len() as u16);
            put16(&mut cd, 0); // extra field length
            put16(&mut cd, 0); // comment length
            put16(&mut cd, 0); // disk number
            put16(&mut cd, 0); // internal attributes
            put32(&mut cd, 0); // external attributes
            put32(&mut cd, e.offset);
            cd.extend_from_slice(&e.name);
        }
        let cd_size = u32::try_from(cd.len()).map_err(|_| too_big())?;
        start.checked_add(cd_size).ok_or_else(too_big)?;

        // End of central directory record.
        let n = self.entries.len() as u16;
        put32(&mut cd, END_OF_CENTRAL_DIRECTORY);
        put16(&mut cd, 0); // this disk
        put16(&mut cd, 0); // disk with the central directory
        put16(&mut cd, n); // entries on this disk
        put16(&mut cd, n); // entries in all
        put32(&mut cd, cd_size);
        put32(&mut cd, start);
        put16(&mut cd, 0); // comment length
        self.out.write_all(&cd)?;
        Ok(self.out)
    }
}

fn put16(v: &mut Vec<u8>, x: u16) {
    v.extend_from_slice(&x.to_le_bytes());
}

fn put32(v: &mut Vec<u8>, x: u32) {
    v.extend_from_slice(&x.to_le_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
        // Bit-at-a-time reference for a longer input.
        let data: Vec<u8> = (0..1000u32).map(|i| (i * 7 + 3) as u8).collect();
        let mut c = !0u32;
        for &b in &data {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
        }
        assert_eq!(crc32(&data), !c);
    }

    #[test]
    fn empty_archive_is_only_the_end_record() {
        let bytes = ZipWriter::new(Vec::new()).finish().unwrap();
        assert_eq!(bytes.len(), 22);
        assert_eq!(&bytes[..4], &[0x50, 0x4b, 0x05, 0x06]);
    }
}
