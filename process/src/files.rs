//! Output files written together: all of them, or none. A command that writes several
//! files (a report, a URDF and its start pose, a trace and its pictures) must not leave
//! some of them behind when one cannot be written.

use std::path::{Path, PathBuf};

/// A file that could not be written, and why.
#[derive(Debug)]
pub struct WriteError {
    /// The file.
    pub path: PathBuf,
    /// What the system said.
    pub source: std::io::Error,
}

impl std::fmt::Display for WriteError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "writing {}: {}", self.path.display(), self.source)
    }
}

impl std::error::Error for WriteError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.source)
    }
}

/// Files to write together; [`Outputs::commit`] writes them.
#[derive(Debug, Default)]
pub struct Outputs {
    files: Vec<(PathBuf, Vec<u8>)>,
}

impl Outputs {
    /// No files yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a file.
    pub fn add(&mut self, path: impl Into<PathBuf>, bytes: impl Into<Vec<u8>>) {
        self.files.push((path.into(), bytes.into()));
    }

    /// The paths of the files added, in order.
    pub fn paths(&self) -> Vec<PathBuf> {
        self.files.iter().map(|(p, _)| p.clone()).collect()
    }

    /// Writes every file under a temporary name beside it, then renames each into place.
    /// If any cannot be written, the temporaries are removed and no file is changed; a
    /// rename fails only where the directory itself changed meanwhile.
    pub fn commit(self) -> Result<(), WriteError> {
        let mut written: Vec<(PathBuf, &Path)> = Vec::with_capacity(self.files.len());
        for (path, bytes) in &self.files {
            let tmp = temporary(path);
            // A directory in a file's place would refuse only the rename, after others.
            let written_here = if path.is_dir() {
                Err(std::io::Error::new(
                    std::io::ErrorKind::IsADirectory,
                    "a directory is in the way",
                ))
            } else {
                std::fs::write(&tmp, bytes)
            };
            if let Err(source) = written_here {
                let _ = std::fs::remove_file(&tmp);
                for (t, _) in &written {
                    let _ = std::fs::remove_file(t);
                }
                return Err(WriteError {
                    path: path.clone(),
                    source,
                });
            }
            written.push((tmp, path));
        }
        let mut renames = written.iter();
        for (tmp, path) in renames.by_ref() {
            if let Err(source) = std::fs::rename(tmp, path) {
                let _ = std::fs::remove_file(tmp);
                for (t, _) in renames {
                    let _ = std::fs::remove_file(t);
                }
                return Err(WriteError {
                    path: path.to_path_buf(),
                    source,
                });
            }
        }
        Ok(())
    }
}

/// A temporary name beside `path`: hidden, and naming this process.
fn temporary(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map_or_else(|| "output".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!(".{name}.{}.partial", std::process::id()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("strider-files-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn entries(d: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn all_files_are_written() {
        let d = scratch("all");
        let mut o = Outputs::new();
        o.add(d.join("a.txt"), "one");
        o.add(d.join("b.txt"), "two");
        o.commit().unwrap();
        assert_eq!(entries(&d), ["a.txt", "b.txt"]);
        assert_eq!(std::fs::read_to_string(d.join("b.txt")).unwrap(), "two");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn one_unwritable_file_leaves_none_and_no_temporary() {
        let d = scratch("none");
        let mut o = Outputs::new();
        o.add(d.join("a.txt"), "one");
        // A file inside a directory that does not exist cannot be written.
        o.add(d.join("missing").join("b.txt"), "two");
        o.add(d.join("c.txt"), "three");
        let e = o.commit().unwrap_err();
        assert_eq!(e.path, d.join("missing").join("b.txt"));
        assert!(e.to_string().starts_with("writing "), "{e}");
        assert!(entries(&d).is_empty(), "{:?}", entries(&d));
        // A directory where the last file goes: the first is not written either.
        std::fs::create_dir(d.join("c.txt")).unwrap();
        let mut o = Outputs::new();
        o.add(d.join("a.txt"), "one");
        o.add(d.join("c.txt"), "three");
        assert_eq!(o.commit().unwrap_err().path, d.join("c.txt"));
        assert_eq!(entries(&d), ["c.txt"]);
        std::fs::remove_dir_all(&d).unwrap();
    }
}
