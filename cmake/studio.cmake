# The studio's page (web/, docs/studio.md): three.js and lil-gui bundled by esbuild into
# BUILD/studio/, where the CLI in BUILD/ finds it, and installed to share/flockmorph/studio/,
# where the installed CLI (bin/flockmorph) finds it. The npm packages come from `npm ci` in web/
# (tools/setup.sh runs it, from web/package-lock.json); without Node or them the page is not
# built, the CLI says so, and the browser tests skip.
find_program(FM_NODE NAMES node nodejs)
set(FM_STUDIO_PAGE_DIR ${CMAKE_BINARY_DIR}/studio)
set(FM_WEB ${PROJECT_SOURCE_DIR}/web)
file(GLOB FM_WEB_SOURCES CONFIGURE_DEPENDS ${FM_WEB}/src/*.js ${FM_WEB}/src/*.css ${FM_WEB}/index.html)
if(FM_NODE AND EXISTS ${FM_WEB}/node_modules/esbuild AND EXISTS ${FM_WEB}/node_modules/three)
  add_custom_command(OUTPUT ${FM_STUDIO_PAGE_DIR}/index.html ${FM_STUDIO_PAGE_DIR}/app.js
    COMMAND ${FM_NODE} ${FM_WEB}/build.mjs --outdir ${FM_STUDIO_PAGE_DIR}
    DEPENDS ${FM_WEB_SOURCES} ${FM_WEB}/build.mjs ${FM_WEB}/package-lock.json
    COMMENT "Building the studio's page (esbuild)"
    VERBATIM)
  add_custom_target(studio_page ALL DEPENDS ${FM_STUDIO_PAGE_DIR}/index.html)
  add_dependencies(flockmorph_cli studio_page)
  set(FM_STUDIO_PAGE_BUILT ON)
  install(DIRECTORY ${FM_STUDIO_PAGE_DIR}/ DESTINATION ${CMAKE_INSTALL_DATADIR}/flockmorph/studio)
else()
  message(STATUS "The studio's page is not built: it needs node and `npm ci` in web/ (tools/setup.sh)")
  set(FM_STUDIO_PAGE_BUILT OFF)
endif()
