// Uses the installed public API only: version, requirements, and the check of a device that
// was never handed in, by check_device() and VirtualTexture::create() (errors as values, never
// an abort). Built with TVT_WITH_COMPOSE, it also calls the compose component
// (terravt::compose::create_virtual_texture); without, it is a client that streams baked
// stores and must not link the compose component's libraries (checked by check_package.sh).
#include <terravt/terravt.h>
#ifdef TVT_WITH_COMPOSE
#include <terravt/compose.h>
#endif

#include <cstdio>
#include <cstring>
#include <string>

int main() {
  const terravt::Version v = terravt::version();
  if (v.major != TERRAVT_VERSION_MAJOR || v.minor != TERRAVT_VERSION_MINOR || v.patch != TERRAVT_VERSION_PATCH ||
      std::strcmp(terravt::version_string(), TERRAVT_VERSION_STRING) != 0) {
    std::printf("FAIL: headers say %s, library says %s\n", TERRAVT_VERSION_STRING, terravt::version_string());
    return 1;
  }
  const terravt::DeviceRequirements r = terravt::device_requirements();
  int required = 0;
  for (const terravt::FeatureRequirement& f : r.features) required += f.required ? 1 : 0;
  if (r.min_api_version < VK_API_VERSION_1_3 || required == 0) {
    std::printf("FAIL: device_requirements() lists no required feature\n");
    return 1;
  }
  const terravt::Status s = terravt::check_device(terravt::DeviceHandles{});
  if (s.ok() || s.error().kind != terravt::ErrorKind::invalid_argument ||
      std::strstr(s.error().message.c_str(), "DeviceHandles::") == nullptr) {
    std::printf("FAIL: check_device on empty handles: %s\n", s.ok() ? "accepted" : s.error().message.c_str());
    return 1;
  }
  // The virtual texture refuses a device that was never handed in, as a value.
  auto vt = terravt::VirtualTexture::create(terravt::DeviceHandles{}, terravt::VirtualTextureDesc{});
  if (vt.ok() || vt.error().message.find("DeviceHandles::") == std::string::npos) {
    std::printf("FAIL: VirtualTexture::create on empty handles: %s\n", vt.ok() ? "accepted" : vt.error().message.c_str());
    return 1;
  }
#ifdef TVT_WITH_COMPOSE
  auto composed = terravt::compose::create_virtual_texture(terravt::DeviceHandles{}, terravt::VirtualTextureDesc{});
  if (composed.ok() || composed.error().message.find("DeviceHandles::") == std::string::npos) {
    std::printf("FAIL: compose::create_virtual_texture on empty handles: %s\n",
                composed.ok() ? "accepted" : composed.error().message.c_str());
    return 1;
  }
  auto composer = terravt::compose::PageComposer::create(terravt::DeviceHandles{}, terravt::VirtualTextureDesc{});
  if (composer.ok() || composer.error().message.find("DeviceHandles::") == std::string::npos) {
    std::printf("FAIL: compose::PageComposer::create on empty handles: %s\n",
                composer.ok() ? "accepted" : composer.error().message.c_str());
    return 1;
  }
  std::printf("compose component linked\n");
#endif
  std::printf("terravt %s: %zu features (%d required); empty handles: %s\n", terravt::version_string(),
              r.features.size(), required, s.error().message.c_str());
  return 0;
}
