// Page-table entry layout, one uint32, shared by vt/page_table.h (C++, no GLM: this header
// needs nothing but <cstdint>) and the GLSL that decodes it.
//   bits  0..19  slot of the data page (physical cache slot, < 2^20)
//   bits 20..24  mip of the data page (>= the entry's own mip; < 32)
//   bits 25..30  zero (reserved)
//   bit  31      valid
#ifndef TVT_SHARED_PAGE_TABLE_ENTRY_H
#define TVT_SHARED_PAGE_TABLE_ENTRY_H

#ifdef __cplusplus
#include <cstdint>
#define TVT_PTE_UINT std::uint32_t
#define TVT_PTE_CONST inline constexpr std::uint32_t
#define TVT_PTE_FN inline constexpr
namespace tvt::gpu {
#else
#define TVT_PTE_UINT uint
#define TVT_PTE_CONST const uint
#define TVT_PTE_FN
#endif

TVT_PTE_CONST TVT_PTE_SLOT_BITS = 20u;
TVT_PTE_CONST TVT_PTE_SLOT_MASK = (1u << TVT_PTE_SLOT_BITS) - 1u;
TVT_PTE_CONST TVT_PTE_MIP_SHIFT = 20u;
TVT_PTE_CONST TVT_PTE_MIP_MASK = 0x1fu;
TVT_PTE_CONST TVT_PTE_VALID = 0x80000000u;

TVT_PTE_FN TVT_PTE_UINT tvt_pte_pack(TVT_PTE_UINT slot, TVT_PTE_UINT data_mip) {
  return TVT_PTE_VALID | ((data_mip & TVT_PTE_MIP_MASK) << TVT_PTE_MIP_SHIFT) | (slot & TVT_PTE_SLOT_MASK);
}
TVT_PTE_FN bool tvt_pte_valid(TVT_PTE_UINT e) { return (e & TVT_PTE_VALID) != 0u; }
TVT_PTE_FN TVT_PTE_UINT tvt_pte_slot(TVT_PTE_UINT e) { return e & TVT_PTE_SLOT_MASK; }
TVT_PTE_FN TVT_PTE_UINT tvt_pte_mip(TVT_PTE_UINT e) { return (e >> TVT_PTE_MIP_SHIFT) & TVT_PTE_MIP_MASK; }

#ifdef __cplusplus
}  // namespace tvt::gpu
#endif
#endif
