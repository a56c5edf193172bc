// TERRAVT_API marks what libterravt exports; everything else in it is hidden.
#pragma once
#if defined(__GNUC__) || defined(__clang__)
#define TERRAVT_API __attribute__((visibility("default")))
#else
#define TERRAVT_API
#endif
