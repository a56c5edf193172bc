# terravt_embed_shaders(TARGET <name> SOURCES <a.comp> ... DEPENDS <headers>)
# Compiles each GLSL file to SPIR-V with glslangValidator at build time (`--vn` emits the words
# as a C array) and embeds it, exposing `std::span<const uint32_t> tvt::shaders::<stem>_<ext>()`
# from the generated header <embedded_shaders.h>.
function(terravt_embed_shaders)
  cmake_parse_arguments(ARG "" "TARGET" "SOURCES;DEPENDS" ${ARGN})
  set(out_dir ${CMAKE_CURRENT_BINARY_DIR}/spv)
  file(MAKE_DIRECTORY ${out_dir}/include)
  set(generated)
  set(decls "")
  foreach(src ${ARG_SOURCES})
    get_filename_component(name ${src} NAME)
    string(REPLACE "." "_" sym ${name})
    set(words_h ${out_dir}/${name}.words.h)
    set(cpp ${out_dir}/${name}.cpp)
    add_custom_command(
      OUTPUT ${words_h}
      COMMAND ${GLSLANG_VALIDATOR} -V --target-env vulkan1.3 -I${CMAKE_CURRENT_SOURCE_DIR}
              --vn k_${sym} -o ${words_h} ${CMAKE_CURRENT_SOURCE_DIR}/${src}
      DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/${src} ${ARG_DEPENDS}
      COMMENT "glslang ${name}"
      VERBATIM)
    file(WRITE ${cpp}.in
      "#include <cstdint>\n#include <span>\n#include \"${name}.words.h\"\nnamespace tvt::shaders {\nstd::span<const uint32_t> ${sym}() { return {k_${sym}, sizeof(k_${sym}) / sizeof(uint32_t)}; }\n}\n")
    configure_file(${cpp}.in ${cpp} COPYONLY)
    set_source_files_properties(${cpp} PROPERTIES OBJECT_DEPENDS ${words_h})
    list(APPEND generated ${cpp})
    string(APPEND decls "std::span<const uint32_t> ${sym}();\n")
  endforeach()
  file(WRITE ${out_dir}/embedded_shaders.h.in
    "#pragma once\n// Generated: SPIR-V words of every shader, compiled at build time.\n#include <cstdint>\n#include <span>\nnamespace tvt::shaders {\n${decls}}\n")
  configure_file(${out_dir}/embedded_shaders.h.in ${out_dir}/include/embedded_shaders.h COPYONLY)
  file(WRITE ${out_dir}/index.cpp.in "#include \"embedded_shaders.h\"\n")
  configure_file(${out_dir}/index.cpp.in ${out_dir}/index.cpp COPYONLY)
  add_library(${ARG_TARGET} STATIC ${out_dir}/index.cpp ${generated})
  target_include_directories(${ARG_TARGET} PUBLIC ${out_dir}/include PRIVATE ${out_dir})
  target_compile_features(${ARG_TARGET} PUBLIC cxx_std_20)
endfunction()
