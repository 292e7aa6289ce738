//! Signing keys: 32 secret bytes that never appear in any output.
//!
//! A key reaches mavtables as a file named by a `signing_key` statement. The file holds
//! either the key itself, as 64 hexadecimal digits, or a passphrase, from which the key
//! is derived exactly as MAVProxy's `signing setup PASSPHRASE` and Mission Planner derive
//! theirs: the SHA-256 digest of the passphrase's bytes. See [`SigningKey::parse`] for the
//! precise rule and [`SigningKey::read_file`] for the checks made on the file.

use crate::files::{FileError, RegularFile, size_text};
use sha2::{Digest, Sha256};
use std::fmt;
use std::path::{Path, PathBuf};

/// The largest key file read (4 KiB): a key is 64 hexadecimal digits and a passphrase a
/// line of text, so anything larger is a mistaken path (a log, a disk image), not a key.
pub(crate) const KEY_FILE_LIMIT: u64 = 4096;

/// A MAVLink 2 signing key. Its `Debug` output does not show the key.
#[derive(Clone, PartialEq, Eq)]
pub struct SigningKey([u8; 32]);

impl SigningKey {
    /// The key made of these 32 bytes.
    pub fn from_bytes(bytes: [u8; 32]) -> Self {
        SigningKey(bytes)
    }

    /// The secret bytes, for computing signatures.
    pub fn as_bytes(&self) -> &[u8; 32] {
        &self.0
    }

    /// The key MAVProxy (`signing setup PASSPHRASE`) and Mission Planner derive from a
    /// passphrase: SHA-256 of its UTF-8 bytes. (MAVProxy encodes the passphrase as ASCII,
    /// so only ASCII passphrases can be shared with it.)
    pub fn from_passphrase(passphrase: &str) -> Self {
        SigningKey(Sha256::digest(passphrase.as_bytes()).into())
    }

    /// The key held in a key file's `contents`.
    ///
    /// One trailing line ending (`\n` or `\r\n`) is removed first. If what remains,
    /// ignoring surrounding whitespace, is exactly 64 hexadecimal digits (either case), they
    /// are the 32 key bytes. Anything else is a passphrase, used as written (inner and
    /// surrounding spaces included) and turned into the key by
    /// [`SigningKey::from_passphrase`]; it must be valid UTF-8 and not empty or only
    /// whitespace. A passphrase that is itself 64 hexadecimal digits is therefore read as
    /// a raw key.
    pub fn parse(contents: &[u8]) -> Result<SigningKey, KeyError> {
        let body = contents
            .strip_suffix(b"\r\n")
            .or_else(|| contents.strip_suffix(b"\n"))
            .unwrap_or(contents);
        if let Some(key) = hex_key(body.trim_ascii()) {
            return Ok(key);
        }
        if body.trim_ascii().is_empty() {
            return Err(KeyError::new(None, Problem::Empty));
        }
        match std::str::from_utf8(body) {
            Ok(passphrase) => Ok(SigningKey::from_passphrase(passphrase)),
            Err(_) => Err(KeyError::new(None, Problem::NotUtf8)),
        }
    }

    /// Reads and parses (see [`SigningKey::parse`]) the key file at `path`.
    ///
    /// Like ssh with a private key, the file is refused when its permissions let anyone
    /// but its owner read or write it (any of the mode bits `0o077`): the key would be
    /// as good as public. A file that is missing, not a regular file (after following
    /// symlinks), larger than `KEY_FILE_LIMIT`, unreadable or empty is an error too; a
    /// device or FIFO is never read. No error ever shows what the file holds.
    pub fn read_file(path: &Path) -> Result<SigningKey, KeyError> {
        SigningKey::read_file_trusting(path, None)
    }

    /// [`SigningKey::read_file`], except that a file inside `private_dir` is not refused
    /// for its mode: systemd's credentials directory (`$CREDENTIALS_DIRECTORY`, filled
    /// by `LoadCredential=`) is private to the service already, and systemd grants the
    /// service's user access to each file with an ACL, which shows as group bits.
    pub fn read_file_trusting(
        path: &Path,
        private_dir: Option<&Path>,
    ) -> Result<SigningKey, KeyError> {
        let fail = |problem| KeyError::new(Some(path), problem);
        let file = RegularFile::open(path).map_err(|e| fail(Problem::File(e)))?;
        // The mode of the opened file: the one whose contents are read.
        let mode = file_mode(file.metadata());
        let private = private_dir.is_some_and(|dir| inside(path, dir));
        if mode & 0o077 != 0 && !private {
            return Err(fail(Problem::OpenToOthers { mode }));
        }
        let contents = file
            .read_all(KEY_FILE_LIMIT)
            .map_err(|e| fail(Problem::File(e)))?;
        SigningKey::parse(&contents).map_err(|e| fail(e.problem))
    }

    /// A short name for the key that does not reveal it: the first 8 bytes of
    /// SHA-256(`"mavtables key fingerprint"` ‖ key). Saved state names keys by it.
    pub fn fingerprint(&self) -> [u8; 8] {
        let mut hasher = Sha256::new();
        hasher.update(b"mavtables key fingerprint");
        hasher.update(self.0);
        let digest = hasher.finalize();
        let mut out = [0u8; 8];
        out.copy_from_slice(&digest[..8]);
        out
    }
}

impl fmt::Debug for SigningKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("SigningKey(<secret>)")
    }
}

/// True if `path` (followed to the real file) lies in directory `dir`.
fn inside(path: &Path, dir: &Path) -> bool {
    match (std::fs::canonicalize(path), std::fs::canonicalize(dir)) {
        (Ok(p), Ok(d)) => p.starts_with(d),
        _ => false,
    }
}

/// The 32 bytes written as exactly 64 hexadecimal digits in `text`, if it is that.
fn hex_key(text: &[u8]) -> Option<SigningKey> {
    if text.len() != 64 {
        return None;
    }
    let mut key = [0u8; 32];
    for (byte, pair) in key.iter_mut().zip(text.chunks_exact(2)) {
        let high = char::from(pair[0]).to_digit(16)?;
        let low = char::from(pair[1]).to_digit(16)?;
        *byte = u8::try_from(high * 16 + low).ok()?;
    }
    Some(SigningKey(key))
}

#[cfg(unix)]
fn file_mode(meta: &std::fs::Metadata) -> u32 {
    use std::os::unix::fs::PermissionsExt;
    meta.permissions().mode() & 0o7777
}

#[cfg(not(unix))]
fn file_mode(_meta: &std::fs::Metadata) -> u32 {
    0o600
}

/// Why a key could not be had. Its text names the file and the problem, never the
/// file's contents.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct KeyError {
    path: Option<PathBuf>,
    problem: Problem,
}

/// What was wrong with a key file.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Problem {
    /// Missing, not a regular file, too large or unreadable.
    File(FileError),
    OpenToOthers {
        mode: u32,
    },
    Empty,
    NotUtf8,
}

impl KeyError {
    fn new(path: Option<&Path>, problem: Problem) -> Self {
        KeyError {
            path: path.map(Path::to_path_buf),
            problem,
        }
    }

    /// The file the error is about (`None` for [`SigningKey::parse`] errors).
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// True when the file was refused for its permissions.
    pub fn is_permissions(&self) -> bool {
        matches!(self.problem, Problem::OpenToOthers { .. })
    }

    /// What is wrong, in one line.
    pub(crate) fn summary(&self) -> String {
        let file = match &self.path {
            Some(p) => format!("key file {}", p.display()),
            None => "key file".to_string(),
        };
        match &self.problem {
            Problem::File(e) => format!("{file} {e}"),
            Problem::OpenToOthers { mode } => {
                format!("{file} can be read or written by other users (mode {mode:04o})")
            }
            Problem::Empty => format!("{file} is empty"),
            Problem::NotUtf8 => {
                format!("{file} holds neither 64 hexadecimal digits nor a UTF-8 passphrase")
            }
        }
    }

    /// What to do about it, when there is something to say.
    pub(crate) fn hint(&self) -> Option<String> {
        let path = self
            .path
            .as_ref()
            .map_or_else(|| "FILE".to_string(), |p| p.display().to_string());
        match &self.problem {
            Problem::OpenToOthers { .. } => Some(format!(
                "a signing key must be private to its owner: run 'chmod 600 {path}'"
            )),
            Problem::Empty | Problem::NotUtf8 => Some(
                "write the key as 64 hexadecimal digits, or a passphrase (the key is its SHA-256, as MAVProxy's 'signing setup')"
                    .to_string(),
            ),
            Problem::File(FileError::TooLarge { .. }) => Some(format!(
                "a key file holds 64 hexadecimal digits or a one-line passphrase, never more than {}",
                size_text(KEY_FILE_LIMIT)
            )),
            Problem::File(_) => None,
        }
    }
}

impl fmt::Display for KeyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.summary())?;
        if let Some(hint) = self.hint() {
            write!(f, "; {hint}")?;
        }
        Ok(())
    }
}

impl std::error::Error for KeyError {}

#[cfg(test)]
mod tests {
    use super::*;

    fn hex(bytes: &[u8]) -> String {
        bytes.iter().map(|b| format!("{b:02x}")).collect()
    }

    // Vectors from Python: hashlib.sha256(b'...').hexdigest().
    const HORSE: &str = "c4bbcb1fbec99d65bf59d85c8cb62ee2db963f0fe106f483d9afa73bd4e39a8a";

    #[test]
    fn passphrase_is_sha256_of_its_bytes() {
        let key = SigningKey::from_passphrase("correct horse battery staple");
        assert_eq!(hex(key.as_bytes()), HORSE);
        // hashlib.sha256('pässwörd'.encode()).hexdigest()
        assert_eq!(
            hex(SigningKey::from_passphrase("pässwörd").as_bytes()),
            "46970bef70aced8123f0d5d094717e2a5cd412041e03b26376049fe65b2834a4"
        );
    }

    #[test]
    fn files_of_a_passphrase_lose_one_line_ending_only() {
        let want = SigningKey::from_passphrase("correct horse battery staple");
        for contents in [
            &b"correct horse battery staple"[..],
            b"correct horse battery staple\n",
            b"correct horse battery staple\r\n",
        ] {
            assert_eq!(SigningKey::parse(contents), Ok(want.clone()));
        }
        assert_eq!(
            SigningKey::parse(b" correct horse battery staple\n"),
            Ok(SigningKey::from_passphrase(" correct horse battery staple"))
        );
        assert_eq!(
            SigningKey::parse(b"correct horse battery staple\n\n"),
            Ok(SigningKey::from_passphrase(
                "correct horse battery staple\n"
            ))
        );
    }

    #[test]
    fn sixty_four_hex_digits_are_the_key_itself() {
        let key = SigningKey::parse(format!("  {}\n", HORSE.to_uppercase()).as_bytes())
            .expect("a hex key");
        assert_eq!(hex(key.as_bytes()), HORSE);
        // 63 or 65 digits, or a non-hex digit, make a passphrase.
        let short = &HORSE[..63];
        assert_eq!(
            SigningKey::parse(short.as_bytes()),
            Ok(SigningKey::from_passphrase(short))
        );
        let long = format!("{HORSE}0");
        assert_eq!(
            SigningKey::parse(long.as_bytes()),
            Ok(SigningKey::from_passphrase(&long))
        );
        let not_hex = format!("g{}", &HORSE[1..]);
        assert_eq!(
            SigningKey::parse(not_hex.as_bytes()),
            Ok(SigningKey::from_passphrase(&not_hex))
        );
    }

    #[test]
    fn empty_or_binary_contents_are_refused() {
        for contents in [&b""[..], b"\n", b"\r\n", b"  \t \n"] {
            let e = SigningKey::parse(contents).expect_err("empty");
            assert_eq!(e.summary(), "key file is empty");
        }
        let e = SigningKey::parse(b"\xff\xfesecret").expect_err("binary");
        assert!(e.summary().contains("neither 64 hexadecimal digits"));
        assert!(!e.to_string().contains("secret"));
    }

    #[cfg(unix)]
    #[test]
    fn a_file_in_the_credentials_directory_may_show_group_bits() {
        use std::os::unix::fs::PermissionsExt;
        let base = std::env::temp_dir().join(format!("mavtables-creds-{}", std::process::id()));
        let creds = base.join("credentials");
        std::fs::create_dir_all(&creds).expect("dir");
        let inner = creds.join("gcs.key");
        let outer = base.join("gcs.key");
        for f in [&inner, &outer] {
            std::fs::write(f, "secret words\n").expect("write");
            std::fs::set_permissions(f, std::fs::Permissions::from_mode(0o440)).expect("mode");
        }
        let trusted = Some(creds.as_path());
        assert!(SigningKey::read_file_trusting(&inner, trusted).is_ok());
        assert!(SigningKey::read_file_trusting(&outer, trusted).is_err());
        assert!(SigningKey::read_file(&inner).is_err());
        let _ = std::fs::remove_dir_all(&base);
    }

    #[test]
    fn fingerprint_names_the_key_without_showing_it() {
        let mut bytes = [0u8; 32];
        for (i, b) in bytes.iter_mut().enumerate() {
            *b = i as u8;
        }
        // hashlib.sha256(b'mavtables key fingerprint' + bytes(range(32))).hexdigest()[:16]
        let key = SigningKey::from_bytes(bytes);
        assert_eq!(hex(&key.fingerprint()), "d78ce0d89a9954dd");
        assert_ne!(
            key.fingerprint(),
            SigningKey::from_bytes([0; 32]).fingerprint()
        );
        assert_eq!(format!("{key:?}"), "SigningKey(<secret>)");
    }
}
