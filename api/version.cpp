// terravt::version(): the library's own version, fixed at configure time.
#include "terravt/version.h"

namespace terravt {

Version version() noexcept { return {TERRAVT_VERSION_MAJOR, TERRAVT_VERSION_MINOR, TERRAVT_VERSION_PATCH}; }

const char* version_string() noexcept { return TERRAVT_VERSION_STRING; }

}  // namespace terravt
