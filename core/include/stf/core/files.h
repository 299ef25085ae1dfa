// Putting bytes on disk so that a full disk, a failing device or a kill never loses a valid
// file: every step is checked (write, fsync, close, rename), and an existing file is replaced
// only by a complete one.
#pragma once

#include <string>
#include <string_view>

namespace stf {

// Writes `bytes` to `path` (created, or emptied when it exists; never through a symbolic
// link), flushes them to the device and closes it, checking each step. Throws std::runtime_error "cannot write NAME: REASON",
// REASON the system's ("No space left on device", "File too large"); `name` is how messages
// call the file (the user's name for it, not a temporary's).
void write_durably(const std::string& path, std::string_view bytes, const std::string& name);

// Flushes a file another writer finished (a script's output) to the device, checking it.
// Throws std::runtime_error "cannot write NAME: REASON".
void sync_file(const std::string& path, const std::string& name);

// Replaces `path` by `bytes` through PATH.tmp-PID beside it, renamed into place only when all
// of it is on the device (orphaned temporaries of `path` removed first); on any failure the
// temporary is removed and an existing file at `path` is left as it was. Throws std::runtime_error
// naming `path` and the reason.
void replace_file(const std::string& path, std::string_view bytes);

// Removes the files PREFIX + PID in `folder` (with `tail` > 0: PREFIX + PID + "-" + `tail`
// more characters, as mkstemp makes them) whose process no longer runs: temporaries a kill -9,
// which no handler sees, left behind.
void remove_orphans(const std::string& folder, const std::string& prefix, int tail = 0);

// Flushes a folder's entries (a rename into it) to the device; best effort.
void sync_folder_of(const std::string& path);

}  // namespace stf
