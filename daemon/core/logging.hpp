// ptdad's logging: spdlog to the journal (native fields, priority) when systemd connected stdout/stderr
// to it ($JOURNAL_STREAM), to the terminal (stderr) otherwise. Only the main thread (supervisor,
// lifecycle) logs; the real-time threads count events instead.
#pragma once

#include <string>

namespace ptda::daemon {

enum class LogTarget { kAuto = 0, kTerminal = 1, kJournal = 2 };

/// True when $JOURNAL_STREAM is set, i.e. systemd connected our stderr to the journal.
/// Thread: main, start-up (getenv).
[[nodiscard]] bool under_journal() noexcept;

/// Installs the default spdlog logger "ptdad" for `target` at `level` ("trace".."error"; unknown =
/// info). Thread: main, before any other thread logs. Allocates; throws ptda::Error when the journal
/// sink cannot be created.
void setup_logging(LogTarget target, const std::string& level);

/// Changes the level of the default logger (SIGHUP reload). Thread: main.
void set_log_level(const std::string& level);

}  // namespace ptda::daemon
