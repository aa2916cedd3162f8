# snow_embed_shaders(<target> <output.cpp> <files...>)
# Embeds shader sources into the binary so an installed snowmodel runs
# without the source tree. The generated file defines
# snow::gl::embedded_shader_sources() (see src/gl/shader_sources.h).
function(snow_embed_shaders target out)
  set(files ${ARGN})
  add_custom_command(
    OUTPUT ${out}
    COMMAND ${CMAKE_COMMAND} -DOUT=${out} "-DFILES=${files}"
            -P ${PROJECT_SOURCE_DIR}/cmake/EmbedShadersScript.cmake
    DEPENDS ${files} ${PROJECT_SOURCE_DIR}/cmake/EmbedShadersScript.cmake
    COMMENT "Embedding shaders"
    VERBATIM)
  target_sources(${target} PRIVATE ${out})
endfunction()
