//! Bounded reads of the files mavtables is given by name: the configuration, key files
//! and the signing state. Each must be a regular file (after following symlinks) of at
//! most a stated size; a device, FIFO, socket or directory is refused without being read,
//! and so is a file over the limit, so a mistaken or hostile path (`/dev/zero`, a FIFO
//! without a writer, a huge file) costs neither memory nor a hang.
//!
//! The path is looked at first, so that a device is not even opened (opening a serial
//! port can reset the board behind it). Then the file is opened without blocking (opening
//! a FIFO would otherwise wait for a writer) and the opened handle is looked at again, so
//! that what is read is what was checked even if the path changed in between; at most
//! one byte more than the limit is read.
//!
//! Files mavtables writes by replacing them (the signing state, the list of recordings)
//! go through [`replace_file`], which only ever removes or overwrites a name of its own.

use std::fmt;
use std::fs::{File, FileType, Metadata, OpenOptions};
use std::io::{self, Read, Write};
use std::os::unix::fs::{FileTypeExt, MetadataExt, OpenOptionsExt};
use std::path::Path;

/// Why a file could not be read. Its text never shows what the file holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FileError {
    /// Nothing is at the path (or a symlink there leads nowhere).
    NotFound,
    /// Something other than a regular file is there.
    NotRegular(FileKind),
    /// The file holds more than `limit` bytes.
    TooLarge {
        /// The most bytes allowed.
        limit: u64,
    },
    /// Opening or reading failed: the system's reason, without its error number.
    Unreadable(String),
}

/// What is at a path that is not a regular file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileKind {
    /// A directory.
    Directory,
    /// A named pipe.
    Fifo,
    /// A character device (`/dev/zero`, a terminal, a serial port).
    CharDevice,
    /// A block device (a disk).
    BlockDevice,
    /// A Unix socket.
    Socket,
    /// Anything else.
    Other,
}

impl FileKind {
    fn of(file_type: FileType) -> FileKind {
        if file_type.is_dir() {
            FileKind::Directory
        } else if file_type.is_fifo() {
            FileKind::Fifo
        } else if file_type.is_char_device() {
            FileKind::CharDevice
        } else if file_type.is_block_device() {
            FileKind::BlockDevice
        } else if file_type.is_socket() {
            FileKind::Socket
        } else {
            FileKind::Other
        }
    }

    fn name(self) -> &'static str {
        match self {
            FileKind::Directory => "a directory",
            FileKind::Fifo => "a FIFO",
            FileKind::CharDevice => "a character device",
            FileKind::BlockDevice => "a block device",
            FileKind::Socket => "a socket",
            FileKind::Other => "a special file",
        }
    }
}

impl FileError {
    fn from_io(e: &io::Error) -> FileError {
        if e.kind() == io::ErrorKind::NotFound {
            return FileError::NotFound;
        }
        let text = e.to_string();
        let text = match text.find(" (os error") {
            Some(i) => text[..i].to_string(),
            None => text,
        };
        FileError::Unreadable(text)
    }
}

/// Reads as a predicate of the file: "key file X" followed by it makes the message.
impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FileError::NotFound => f.write_str("does not exist"),
            FileError::NotRegular(kind) => write!(f, "is {}, not a regular file", kind.name()),
            FileError::TooLarge { limit } => {
                write!(f, "is larger than the limit of {}", size_text(*limit))
            }
            FileError::Unreadable(why) => write!(f, "cannot be read: {why}"),
        }
    }
}

impl std::error::Error for FileError {}

/// `bytes` in the largest binary unit that divides it (`4 KiB`, `16 MiB`).
pub(crate) fn size_text(bytes: u64) -> String {
    for (unit, size) in [("GiB", 1u64 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)] {
        if bytes >= size && bytes.is_multiple_of(size) {
            return format!("{} {unit}", bytes / size);
        }
    }
    format!("{bytes} bytes")
}

/// A regular file opened for reading, with what `fstat` said of the open handle.
#[derive(Debug)]
pub(crate) struct RegularFile {
    file: File,
    metadata: Metadata,
}

impl RegularFile {
    /// Opens the regular file at `path` (symlinks followed); anything else is refused
    /// without being read, and devices without being opened.
    pub(crate) fn open(path: &Path) -> Result<RegularFile, FileError> {
        let seen = std::fs::metadata(path).map_err(|e| FileError::from_io(&e))?;
        if !seen.is_file() {
            return Err(FileError::NotRegular(FileKind::of(seen.file_type())));
        }
        let file = OpenOptions::new()
            .read(true)
            .custom_flags(libc::O_NONBLOCK | libc::O_NOCTTY)
            .open(path)
            .map_err(|e| FileError::from_io(&e))?;
        let metadata = file.metadata().map_err(|e| FileError::from_io(&e))?;
        if !metadata.is_file() {
            return Err(FileError::NotRegular(FileKind::of(metadata.file_type())));
        }
        Ok(RegularFile { file, metadata })
    }

    /// The opened file, to be read as a stream (a capture of any size).
    pub(crate) fn into_file(self) -> File {
        self.file
    }

    /// What `fstat` said of the opened file (its mode, owner and size).
    pub(crate) fn metadata(&self) -> &Metadata {
        &self.metadata
    }

    /// The whole file, if it holds at most `limit` bytes (also when it grows while read).
    pub(crate) fn read_all(self, limit: u64) -> Result<Vec<u8>, FileError> {
        let too_large = FileError::TooLarge { limit };
        if self.metadata.len() > limit {
            return Err(too_large);
        }
        let expected = usize::try_from(self.metadata.len()).unwrap_or(0);
        let mut bytes = Vec::with_capacity(expected.saturating_add(1));
        self.file
            .take(limit.saturating_add(1))
            .read_to_end(&mut bytes)
            .map_err(|e| FileError::from_io(&e))?;
        if bytes.len() as u64 > limit {
            return Err(too_large);
        }
        Ok(bytes)
    }
}

/// The whole regular file at `path`, if it holds at most `limit` bytes (see
/// [`RegularFile::open`] for what is refused).
pub(crate) fn read_regular(path: &Path, limit: u64) -> Result<Vec<u8>, FileError> {
    RegularFile::open(path)?.read_all(limit)
}

/// Replaces the file at `path` with `bytes` so that it is the old file or the new one at
/// every moment, even across a power loss: `bytes` go to `temp` (a name of mavtables' own
/// beside `path`), created with `mode`, synced and renamed over `path`; then the
/// directory is synced. When a later step fails, the temporary file it created is
/// removed again. What an earlier save left at `temp` is removed first, but only if it is
/// mavtables' (see [`remove_leftover`]; `mark` is how every file of this kind mavtables
/// writes begins); anything else there fails the save and is left alone.
pub(crate) fn replace_file(
    path: &Path,
    temp: &Path,
    bytes: &[u8],
    mode: u32,
    mark: &[u8],
) -> io::Result<()> {
    remove_leftover(temp, mark)?;
    // Never opens what is there: if something came meanwhile, it is not ours to remove.
    let mut file = OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(mode)
        .open(temp)?;
    let written = file
        .write_all(bytes)
        .and_then(|()| file.sync_all())
        .and_then(|()| std::fs::rename(temp, path));
    if let Err(e) = written {
        let _ = remove_if_same(temp, &file);
        return Err(e);
    }
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty())
        && let Ok(d) = File::open(dir)
    {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Removes the file an interrupted save left at `temp`: only a regular file (a link is
/// never followed nor removed) of the user mavtables runs as, whose first bytes are
/// those of `mark` as far as they go, or zeros (what a power loss leaves of a file whose
/// blocks were not written yet), or nothing. Something else at that name is not
/// mavtables' to remove: an error says so, and it stays.
fn remove_leftover(temp: &Path, mark: &[u8]) -> io::Result<()> {
    let in_the_way = || {
        io::Error::new(
            io::ErrorKind::AlreadyExists,
            format!(
                "{} is in the way, and mavtables did not write it; remove it or move it away",
                temp.display()
            ),
        )
    };
    match std::fs::symlink_metadata(temp) {
        Ok(meta) if meta.is_file() => {}
        Ok(_) => return Err(in_the_way()),
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e),
    }
    let file = OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK | libc::O_NOCTTY)
        .open(temp)?;
    let meta = file.metadata()?;
    if !meta.is_file() || meta.uid() != crate::io::effective_uid() {
        return Err(in_the_way());
    }
    let mut start = Vec::with_capacity(mark.len());
    (&file).take(mark.len() as u64).read_to_end(&mut start)?;
    if !mark.starts_with(&start) && start.iter().any(|&b| b != 0) {
        return Err(in_the_way());
    }
    remove_if_same(temp, &file)
}

/// Removes `path` if it is still the file open as `file` (nothing, if it is gone).
fn remove_if_same(path: &Path, file: &File) -> io::Result<()> {
    let ours = file.metadata()?;
    match std::fs::symlink_metadata(path) {
        Ok(there) if there.dev() == ours.dev() && there.ino() == ours.ino() => {}
        Ok(_) => return Ok(()),
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e),
    }
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != io::ErrorKind::NotFound => Err(e),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;
    use std::process::Command;

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("mavtables-files-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch dir");
        dir
    }

    #[test]
    fn a_regular_file_within_the_limit_is_read_whole() {
        let dir = scratch("ok");
        let path = dir.join("f");
        std::fs::write(&path, b"12345").expect("write");
        assert_eq!(read_regular(&path, 5).as_deref(), Ok(&b"12345"[..]));
        assert_eq!(
            read_regular(&path, 4),
            Err(FileError::TooLarge { limit: 4 })
        );
        std::fs::write(&path, b"").expect("write");
        assert_eq!(read_regular(&path, 0), Ok(Vec::new()));
        let link = dir.join("link");
        std::os::unix::fs::symlink(&path, &link).expect("symlink");
        assert_eq!(read_regular(&link, 0), Ok(Vec::new()));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn anything_but_a_regular_file_is_refused_unread() {
        let dir = scratch("odd");
        assert_eq!(
            read_regular(&dir.join("nope"), 10),
            Err(FileError::NotFound)
        );
        assert_eq!(
            read_regular(&dir, 10),
            Err(FileError::NotRegular(FileKind::Directory))
        );
        assert_eq!(
            read_regular(Path::new("/dev/zero"), 10),
            Err(FileError::NotRegular(FileKind::CharDevice))
        );
        let zero = dir.join("zero");
        std::os::unix::fs::symlink("/dev/zero", &zero).expect("symlink");
        assert_eq!(
            read_regular(&zero, 10),
            Err(FileError::NotRegular(FileKind::CharDevice))
        );
        let fifo = dir.join("fifo");
        let made = Command::new("mkfifo").arg(&fifo).status().expect("mkfifo");
        assert!(made.success());
        assert_eq!(
            read_regular(&fifo, 10),
            Err(FileError::NotRegular(FileKind::Fifo))
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_sparse_file_over_the_limit_is_refused_unread() {
        let dir = scratch("big");
        let path = dir.join("big");
        let f = File::create(&path).expect("create");
        f.set_len(1 << 32).expect("set_len");
        assert_eq!(
            read_regular(&path, 1 << 20),
            Err(FileError::TooLarge { limit: 1 << 20 })
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn messages_read_as_predicates() {
        assert_eq!(FileError::NotFound.to_string(), "does not exist");
        assert_eq!(
            FileError::NotRegular(FileKind::Fifo).to_string(),
            "is a FIFO, not a regular file"
        );
        assert_eq!(
            FileError::TooLarge { limit: 4096 }.to_string(),
            "is larger than the limit of 4 KiB"
        );
        assert_eq!(size_text(16 << 20), "16 MiB");
        assert_eq!(size_text(1000), "1000 bytes");
        let denied = io::Error::from_raw_os_error(libc::EACCES);
        assert_eq!(
            FileError::from_io(&denied).to_string(),
            "cannot be read: Permission denied"
        );
    }
}
