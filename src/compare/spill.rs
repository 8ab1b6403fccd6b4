//! Differences that can be read again in the same order, as often as needed: held in memory,
//! or spilled to a scratch file in sample order (17 bytes each) where there may be more than
//! memory holds (a comparison of 10⁸ samples), so memory stays bounded whatever their number.

use std::fs::File;
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};

/// The class of a difference without a slope.
pub const NO_CLASS: u8 = u8::MAX;
/// Bytes of one spilled record: dh and weight (f64) and the slope class.
const RECORD_BYTES: usize = 17;
/// What the scratch files are named after.
const SPILL_NAME: &str = "terrafuse-compare.spill";
/// Records read at once.
const BLOCK: usize = 1 << 16;

/// One difference: A − B, its weight and the index of the reference's slope class there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Record {
    /// A − B, metres; NaN: none there (a record every statistic leaves out, so records can be
    /// made one per sample, in place).
    pub dh_m: f64,
    /// Its weight (the cell's area in m², or 1).
    pub weight: f64,
    /// Its slope class, or [`NO_CLASS`].
    pub class: u8,
}

impl Record {
    fn encode(&self) -> [u8; RECORD_BYTES] {
        let mut bytes = [0u8; RECORD_BYTES];
        bytes[..8].copy_from_slice(&self.dh_m.to_le_bytes());
        bytes[8..16].copy_from_slice(&self.weight.to_le_bytes());
        bytes[16] = self.class;
        bytes
    }

    fn decode(bytes: &[u8]) -> Record {
        let f64_at = |at: usize| f64::from_le_bytes(bytes[at..at + 8].try_into().unwrap_or([0; 8]));
        Record { dh_m: f64_at(0), weight: f64_at(8), class: bytes[16] }
    }
}

/// Differences that can be read again, in the same order, as often as needed.
pub trait Records: Sync {
    /// Calls `f` with consecutive blocks of the records, in order.
    fn scan(&self, f: &mut dyn FnMut(&[Record])) -> io::Result<()>;

    /// The records all at once where they are held in memory (a pass may then read parts of
    /// them on several threads); None where they can only be scanned.
    fn held(&self) -> Option<&[Record]> {
        None
    }
}

impl Records for Vec<Record> {
    fn scan(&self, f: &mut dyn FnMut(&[Record])) -> io::Result<()> {
        self.chunks(BLOCK).for_each(f);
        Ok(())
    }

    fn held(&self) -> Option<&[Record]> {
        Some(self)
    }
}

/// Records in a scratch file of their own, removed when dropped.
#[derive(Debug)]
pub struct Spill {
    path: PathBuf,
    writer: Option<io::BufWriter<File>>,
    count: u64,
}

impl Spill {
    /// A new, empty scratch file in `dir` (a name no other file there has), after removing
    /// those that killed processes left there.
    pub fn create(dir: &Path) -> io::Result<Spill> {
        for orphan in crate::files::orphans(dir, SPILL_NAME) {
            let _ = std::fs::remove_file(orphan);
        }
        let mut n = 0u32;
        loop {
            // Named as `files` names temporaries, so that `files::orphans` finds them.
            let path = dir.join(format!(".{SPILL_NAME}.tmp-{}-{n}", std::process::id()));
            match File::create_new(&path) {
                Ok(file) => {
                    return Ok(Spill { path, writer: Some(io::BufWriter::with_capacity(1 << 20, file)), count: 0 });
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => n += 1,
                Err(e) => return Err(e),
            }
        }
    }

    /// The scratch file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether no record was pushed.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Appends a record.
    pub fn push(&mut self, record: Record) -> io::Result<()> {
        let Some(writer) = self.writer.as_mut() else {
            return Err(io::Error::other("the scratch file was already finished"));
        };
        writer.write_all(&record.encode())?;
        self.count += 1;
        Ok(())
    }

    /// Ends the writing; the records can be read from now on.
    pub fn finish(&mut self) -> io::Result<()> {
        match self.writer.take() {
            Some(writer) => writer.into_inner().map_err(io::IntoInnerError::into_error).map(drop),
            None => Ok(()),
        }
    }
}

impl Records for Spill {
    fn scan(&self, f: &mut dyn FnMut(&[Record])) -> io::Result<()> {
        if self.writer.is_some() {
            return Err(io::Error::other("the scratch file is still being written"));
        }
        let mut file = File::open(&self.path)?;
        let mut bytes = vec![0u8; BLOCK * RECORD_BYTES];
        let mut records = Vec::with_capacity(BLOCK);
        let mut left = self.count;
        while left > 0 {
            let n = left.min(BLOCK as u64) as usize;
            file.read_exact(&mut bytes[..n * RECORD_BYTES])?;
            records.clear();
            records.extend(bytes[..n * RECORD_BYTES].chunks_exact(RECORD_BYTES).map(Record::decode));
            f(&records);
            left -= n as u64;
        }
        Ok(())
    }
}

impl Drop for Spill {
    fn drop(&mut self) {
        self.writer = None;
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spill_gives_back_what_was_pushed_and_leaves_nothing_behind() {
        let dir = std::env::temp_dir().join(format!("terrafuse-spill-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let pushed: Vec<Record> = (0..BLOCK as u32 + 123)
            .map(|k| {
                let h = crate::maths::pcg(k);
                Record { dh_m: f64::from(h % 1000) * 0.01 - 5.0, weight: 1.0 + f64::from(h % 7), class: (h % 9) as u8 }
            })
            .collect();
        let path = {
            let mut spill = Spill::create(&dir).unwrap();
            let other = Spill::create(&dir).unwrap();
            assert_ne!(spill.path(), other.path());
            for r in &pushed {
                spill.push(*r).unwrap();
            }
            assert!(spill.scan(&mut |_| {}).is_err(), "read before it was finished");
            spill.finish().unwrap();
            let mut read = Vec::new();
            spill.scan(&mut |block| read.extend_from_slice(block)).unwrap();
            let bits =
                |v: &[Record]| v.iter().map(|r| (r.dh_m.to_bits(), r.weight.to_bits(), r.class)).collect::<Vec<_>>();
            assert_eq!(bits(&read), bits(&pushed));
            spill.path().to_path_buf()
        };
        assert!(!path.exists());
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
        // One a killed process left (no process has id 2³¹ − 2) goes with the next one made.
        let orphan = dir.join(format!(".{SPILL_NAME}.tmp-2147483646-0"));
        std::fs::write(&orphan, b"left").unwrap();
        let kept = dir.join(format!(".{SPILL_NAME}.tmp-{}-99", std::process::id()));
        std::fs::write(&kept, b"this process's").unwrap();
        drop(Spill::create(&dir).unwrap());
        assert!(!orphan.exists() && kept.exists());
        std::fs::remove_file(&kept).unwrap();
        std::fs::remove_dir(&dir).unwrap();
    }
}
