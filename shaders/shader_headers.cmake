# terravt_shader_headers: shaders/shared/*.h, the constants and structs shared by GLSL and C++
# (and GLM). Included by shaders/CMakeLists.txt and by the fuzz project (fuzz/CMakeLists.txt).
add_library(terravt_shader_headers INTERFACE)
target_include_directories(terravt_shader_headers INTERFACE ${CMAKE_CURRENT_LIST_DIR})
target_link_libraries(terravt_shader_headers INTERFACE glm::glm)
