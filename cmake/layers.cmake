# The layer table of docs/architecture.md, kept by the compiler. Every project header is included as
# "folder/name.h"; instead of the repository root, a target built from <folder>/ exports only
# <build>/layers/<folder>, a directory holding one link, <folder> -> <source>/<folder>. A target then sees
# the headers of its own folder and of the targets it links (PUBLIC links carry their folders on), so an
# include of a folder it does not link fails to compile ("No such file or directory"), not only the
# Layers test. Links follow the table: a layer links PUBLIC what its headers include and PRIVATE what only
# its sources use.
function(bistable_layer target folder)
  set(dir ${PROJECT_BINARY_DIR}/layers/${folder})
  if(NOT IS_SYMLINK ${dir}/${folder})
    file(MAKE_DIRECTORY ${dir})
    file(CREATE_LINK ${PROJECT_SOURCE_DIR}/${folder} ${dir}/${folder} SYMBOLIC)
  endif()
  target_include_directories(${target} PUBLIC ${dir})
endfunction()
