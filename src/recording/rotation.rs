//! When a recording file is closed for a new one, and which old recordings are removed:
//! beyond `max_files`, and while the disk has less free space than `min_free_bytes`.
//! Oldest first (by modification time, then suffix number, then name); the file being
//! written is never removed.

/// A recording found in the directory.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Existing {
    /// Its file name.
    pub name: String,
    /// Its modification time (any monotonic unit, e.g. nanoseconds since the epoch).
    pub modified: u128,
    /// Its name's suffix number (0 without one): of two files written within one tick
    /// of the file system's clock, the one with the higher suffix is newer.
    pub suffix: u32,
    /// Its size in bytes.
    pub bytes: u64,
}

/// Whether a file holding `size` bytes is closed before `next` more bytes are written,
/// so that it stays within `max` (a file always takes at least one record).
pub(crate) fn must_rotate(size: u64, next: u64, max: u64) -> bool {
    size > 0 && size.saturating_add(next) > max
}

/// The oldest first, the file being written (`current`) left out.
fn removable<'a>(files: &'a [Existing], current: Option<&str>) -> Vec<&'a Existing> {
    let mut old: Vec<&Existing> = files
        .iter()
        .filter(|f| Some(f.name.as_str()) != current)
        .collect();
    old.sort_by(|a, b| (a.modified, a.suffix, &a.name).cmp(&(b.modified, b.suffix, &b.name)));
    old
}

/// The recordings to remove so that at most `max_files` remain (0: no limit), counting
/// `current` (which stays).
pub(crate) fn over_count(files: &[Existing], max_files: u32, current: Option<&str>) -> Vec<String> {
    let max = usize::try_from(max_files).unwrap_or(usize::MAX);
    if max == 0 || files.len() <= max {
        return Vec::new();
    }
    let excess = files.len() - max;
    removable(files, current)
        .into_iter()
        .take(excess)
        .map(|f| f.name.clone())
        .collect()
}

/// What to do before writing `needed` bytes on a disk with `free` bytes free, keeping
/// `min_free` free.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct SpacePlan {
    /// Old recordings to remove first, oldest first.
    pub remove: Vec<String>,
    /// Whether there is room once they are gone (if not, the bytes are not written).
    pub enough: bool,
}

/// Which old recordings to remove, oldest first, so that `needed` bytes can be written
/// and `min_free` bytes stay free; if removing all of them is not enough, none is
/// removed (they are worth more than the records that would not fit anyway).
pub(crate) fn make_room(
    files: &[Existing],
    free: u64,
    needed: u64,
    min_free: u64,
    current: Option<&str>,
) -> SpacePlan {
    let want = min_free.saturating_add(needed);
    if free >= want {
        return SpacePlan {
            remove: Vec::new(),
            enough: true,
        };
    }
    let mut gained = free;
    let mut remove = Vec::new();
    for f in removable(files, current) {
        if gained >= want {
            break;
        }
        gained = gained.saturating_add(f.bytes);
        remove.push(f.name.clone());
    }
    if gained >= want {
        SpacePlan {
            remove,
            enough: true,
        }
    } else {
        SpacePlan {
            remove: Vec::new(),
            enough: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(name: &str, modified: u128, bytes: u64) -> Existing {
        Existing {
            name: name.to_string(),
            modified,
            suffix: 0,
            bytes,
        }
    }

    #[test]
    fn within_one_tick_the_suffix_orders_the_files() {
        let mut files: Vec<Existing> = [10, 2, 0, 1]
            .iter()
            .map(|&n| Existing {
                suffix: n,
                ..file(&format!("t-{n}.tlog"), 7, 1)
            })
            .collect();
        files.push(file("older.tlog", 6, 1));
        assert_eq!(
            over_count(&files, 2, Some("t-10.tlog")),
            ["older.tlog", "t-0.tlog", "t-1.tlog"]
        );
    }

    #[test]
    fn a_file_rotates_before_it_would_pass_the_limit() {
        assert!(!must_rotate(0, 500, 100));
        assert!(!must_rotate(50, 50, 100));
        assert!(must_rotate(51, 50, 100));
        assert!(!must_rotate(u64::MAX, 0, u64::MAX));
    }

    #[test]
    fn the_oldest_go_beyond_the_count_never_the_current_one() {
        let files = [
            file("c", 3, 1),
            file("a", 1, 1),
            file("cur", 0, 1),
            file("b", 1, 1),
        ];
        assert_eq!(over_count(&files, 2, Some("cur")), ["a", "b"]);
        assert_eq!(over_count(&files, 4, Some("cur")), Vec::<String>::new());
        assert_eq!(over_count(&files, 0, Some("cur")), Vec::<String>::new());
        assert_eq!(over_count(&files, 1, None), ["cur", "a", "b"]);
    }

    #[test]
    fn room_is_made_from_the_oldest_or_not_at_all() {
        let files = [
            file("new", 9, 100),
            file("old", 1, 100),
            file("cur", 5, 100),
        ];
        let plan = make_room(&files, 1000, 10, 500, Some("cur"));
        assert_eq!(
            plan,
            SpacePlan {
                remove: vec![],
                enough: true
            }
        );
        let plan = make_room(&files, 450, 10, 500, Some("cur"));
        assert_eq!(plan.remove, ["old"]);
        assert!(plan.enough);
        let plan = make_room(&files, 350, 10, 500, Some("cur"));
        assert_eq!(plan.remove, ["old", "new"]);
        let plan = make_room(&files, 100, 10, 500, Some("cur"));
        assert_eq!(
            plan,
            SpacePlan {
                remove: vec![],
                enough: false
            }
        );
    }
}
