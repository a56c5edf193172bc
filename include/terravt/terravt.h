// terravt: a virtual-texture backend for terrains on Vulkan. This header includes libterravt's
// whole public API; each part may also be included on its own. The compose component (VTs
// composed from a scene, libterravt_compose) has its own header: terravt/compose.h.
#pragma once
#include "terravt/coords.h"
#include "terravt/device.h"
#include "terravt/error.h"
#include "terravt/page_producer.h"
#include "terravt/version.h"
#include "terravt/virtual_texture.h"
