# Writes OUT, the header of `nexdyn --version`: NEXDYN_VERSION (the project's) and NEXDYN_COMMIT
# (`git describe --always --dirty` of SOURCE_DIR, or "unknown" outside a git clone). Run at every
# build (engine/CMakeLists.txt), it rewrites OUT only when the text changes, so a new commit
# recompiles main.cpp and nothing else.
execute_process(COMMAND git -C "${SOURCE_DIR}" describe --always --dirty --abbrev=12
                OUTPUT_VARIABLE commit ERROR_QUIET OUTPUT_STRIP_TRAILING_WHITESPACE RESULT_VARIABLE status)
if(NOT status EQUAL 0 OR commit STREQUAL "")
  set(commit "unknown")
endif()
set(text "#define NEXDYN_VERSION \"${VERSION}\"\n#define NEXDYN_COMMIT \"${commit}\"\n")
set(old "")
if(EXISTS "${OUT}")
  file(READ "${OUT}" old)
endif()
if(NOT old STREQUAL text)
  file(WRITE "${OUT}" "${text}")
endif()
