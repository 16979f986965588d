#include "core/logging.hpp"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/sinks/systemd_sink.h>
#include <spdlog/spdlog.h>

#include <cstdlib>
#include <memory>

#include "ptda/common/error.hpp"

namespace ptda::daemon {

bool under_journal() noexcept {
  const char* s = std::getenv("JOURNAL_STREAM");
  return s != nullptr && *s != '\0';
}

namespace {
spdlog::level::level_enum parse_level(const std::string& level) {
  if (level == "trace") return spdlog::level::trace;
  if (level == "debug") return spdlog::level::debug;
  if (level == "warn") return spdlog::level::warn;
  if (level == "error") return spdlog::level::err;
  return spdlog::level::info;
}
}  // namespace

void setup_logging(LogTarget target, const std::string& level) {
  const bool journal = target == LogTarget::kJournal || (target == LogTarget::kAuto && under_journal());
  std::shared_ptr<spdlog::logger> logger;
  try {
    if (journal) {
      // The journal stamps and tags every entry itself: the message is the text only.
      auto sink = std::make_shared<spdlog::sinks::systemd_sink_st>("ptdad");
      logger = std::make_shared<spdlog::logger>("ptdad", sink);
      logger->set_pattern("%v");
    } else {
      auto sink = std::make_shared<spdlog::sinks::stderr_color_sink_mt>();
      logger = std::make_shared<spdlog::logger>("ptdad", sink);
      logger->set_pattern("%Y-%m-%d %H:%M:%S.%e ptdad %^%l%$: %v");
    }
  } catch (const spdlog::spdlog_ex& e) {
    throw Error(std::string("logging: ") + e.what());
  }
  logger->set_level(parse_level(level));
  logger->flush_on(spdlog::level::info);
  spdlog::set_default_logger(logger);
}

void set_log_level(const std::string& level) {
  spdlog::default_logger()->set_level(parse_level(level));
}

}  // namespace ptda::daemon
