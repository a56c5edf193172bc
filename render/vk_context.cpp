#include "render/vk_context.h"
