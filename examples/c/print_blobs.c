/* print_blobs — prints the blob table of each .decals package named on the
 * command line, through the C API (decal/decal.h). Build it against an
 * installed libdecal:
 *
 *   cc -std=c99 -Wall -Werror print_blobs.c $(pkg-config --cflags --libs decal)
 *
 * Output, per package: a line "package <path> <major>.<minor> <blob count>",
 * then one tab-separated line per blob, in file order:
 *   <index> <id> <name> <type> <stride> <count> <codec> <stored size> <raw size>
 * Exit status: 0 when every package opened, 1 otherwise (the error goes to
 * stderr as "<path>: <status name>: <message>"). */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>

#include <decal/decal.h>

static int print_package(const char* path) {
  decal_error error;
  decal_package* package = NULL;
  if (decal_open_file(path, NULL, &package, &error) != DECAL_OK) {
    fprintf(stderr, "%s: %s: %s\n", path, decal_status_name(error.code), error.message);
    return 1;
  }
  uint32_t major = 0, minor = 0;
  decal_package_version(package, &major, &minor, NULL);
  const uint32_t count = decal_blob_count(package);
  printf("package %s %" PRIu32 ".%" PRIu32 " %" PRIu32 "\n", path, major, minor, count);
  int failed = 0;
  for (uint32_t i = 0; i < count; ++i) {
    decal_blob_info info;
    if (decal_blob_info_at(package, i, &info, &error) != DECAL_OK) {
      fprintf(stderr, "%s: blob %" PRIu32 ": %s\n", path, i, error.message);
      failed = 1;
      continue;
    }
    printf("%" PRIu32 "\t%" PRIu32 "\t%s\t%s\t%" PRIu32 "\t%" PRIu64 "\t%s\t%" PRIu64 "\t%" PRIu64
           "\n",
           info.index, info.id, info.name, info.element_type_name, info.stride, info.count,
           info.codec_name, info.stored_size, info.raw_size);
  }
  decal_close(package);
  return failed;
}

int main(int argc, char** argv) {
  if (argc < 2) {
    fprintf(stderr, "usage: %s PACKAGE.decals...\n", argv[0]);
    return 2;
  }
  /* A library of another major version would not have loaded (SONAME);
   * a header newer than the library is caught here. */
  if (decal_version() / 10000 != DECAL_C_API_VERSION_MAJOR ||
      decal_version() < DECAL_C_API_VERSION) {
    fprintf(stderr, "libdecal %s is older than decal.h %d.%d\n", decal_version_string(),
            DECAL_C_API_VERSION_MAJOR, DECAL_C_API_VERSION_MINOR);
    return 1;
  }
  int failed = 0;
  for (int i = 1; i < argc; ++i) failed |= print_package(argv[i]);
  return failed ? EXIT_FAILURE : EXIT_SUCCESS;
}
