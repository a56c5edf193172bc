#include <gtest/gtest.h>

#include "vt/vt_config.h"

using namespace tvt;

TEST(VtConfig, PackRoundTripsAtTheFarCornerOf2To24) {
  VtConfig c;
  c.log2_size = 24;
  ASSERT_TRUE(validate(c, "t").ok());
  EXPECT_EQ(c.mip_count(), 24u - 7u + 1u);
  const uint64_t n = c.pages_per_side(0);
  EXPECT_EQ(n, uint64_t(1) << 17);
  for (uint32_t mip = 0; mip < c.mip_count(); ++mip) {
    const uint32_t last = uint32_t(c.pages_per_side(mip) - 1);
    const PageId id{mip, last, last};
    EXPECT_TRUE(is_valid(c, id));
    EXPECT_EQ(PageId::unpack(id.pack()), id);
    EXPECT_FALSE(is_valid(c, PageId{mip, last + 1, 0}));
  }
  EXPECT_FALSE(is_valid(c, PageId{c.mip_count(), 0, 0}));
}

TEST(VtConfig, RejectsOutOfRangeFieldsByName) {
  VtConfig c;
  c.page_texels = 100;
  auto s = validate(c, "f.json: /vt");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("/vt/page_texels"), std::string::npos);
  c = VtConfig{};
  c.log2_size = 9;
  EXPECT_NE(validate(c, "x").error().message.find("/log2_size"), std::string::npos);
  c = VtConfig{};
  c.border_texels = 65;
  EXPECT_NE(validate(c, "x").error().message.find("/border_texels"), std::string::npos);
}
