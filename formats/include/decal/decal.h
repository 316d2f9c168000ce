/* decal/decal.h — the C API of the .decals package reader, for engines and
 * languages that cannot use C++ (Unity/C# P/Invoke, Unreal, plain C, Vulkan
 * loaders). C99; usable from C and C++. No C++ type crosses it.
 *
 * It forwards to the C++ reader (decal/reader.hpp, decal/inspect.hpp) and
 * keeps its contract: every file is treated as hostile, every size, offset,
 * index and checksum is checked before use (formats/SPEC.md "Validation"),
 * and no function throws, aborts or longjmps: each returns a decal_status
 * and, when asked, a one-line message. The library is libdecal.so.1
 * (pkg-config name `decal`); docs/c-api.md is the guide.
 *
 * Ownership and lifetimes
 *   - A decal_package is created by decal_open_file / decal_open_memory and
 *     destroyed by decal_close. It owns everything it hands out: blob names,
 *     the metadata text, blob data pointers. These stay valid, unchanged,
 *     until decal_close of that package, and no longer.
 *   - decal_open_memory copies the caller's bytes: the caller may free or
 *     reuse them as soon as the call returns.
 *   - decal_error is caller memory, written by the call it was passed to.
 *
 * Thread-safety
 *   - A package is immutable once opened. Every function taking a
 *     `const decal_package*` may be called from any number of threads at
 *     once on the same package. decal_close must not run concurrently with
 *     any other call on that package.
 *   - Different packages are independent. There is no global state: no
 *     init call, no thread-local "last error".
 *
 * Errors
 *   Every function that can fail returns a decal_status and takes a last
 *   `decal_error* error` that may be NULL. On failure, when error is not
 *   NULL, error->code is the returned status and error->message a
 *   NUL-terminated line that says what was wrong and where (file, byte
 *   offset, blob, value), truncated to fit. On success error->code is
 *   DECAL_OK and error->message is "". Out-parameters are written only as
 *   each function says.
 *
 * Versioning (ABI policy, docs/c-api.md "Versioning")
 *   DECAL_C_API_VERSION_MAJOR is the SONAME (libdecal.so.1). Within a major
 *   version, functions, enum values and struct layouts are never removed
 *   or changed; a minor version only adds functions and enum values. A
 *   struct that needs a new field gets a new struct and function instead.
 *   decal_version() reports the library actually loaded, which may be a
 *   newer minor than this header.
 */
#ifndef DECAL_DECAL_H
#define DECAL_DECAL_H

/* A C header, so C's typedefs and headers: clang-tidy's C++ modernize checks
 * do not apply. NOLINTBEGIN(modernize-use-using,modernize-deprecated-headers) */
#include <stddef.h>
#include <stdint.h>

#if defined(_WIN32)
#if defined(DECAL_BUILDING_LIBRARY)
#define DECAL_API __declspec(dllexport)
#else
#define DECAL_API __declspec(dllimport)
#endif
#elif defined(__GNUC__)
#define DECAL_API __attribute__((visibility("default")))
#else
#define DECAL_API
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* Version of this C API (the header). */
#define DECAL_C_API_VERSION_MAJOR 1
#define DECAL_C_API_VERSION_MINOR 0
#define DECAL_C_API_VERSION_PATCH 0
/* major * 10000 + minor * 100 + patch, as decal_version() returns. */
#define DECAL_C_API_VERSION \
  (DECAL_C_API_VERSION_MAJOR * 10000 + DECAL_C_API_VERSION_MINOR * 100 + DECAL_C_API_VERSION_PATCH)

/* The package format this library reads (formats/SPEC.md "Versioning"): a
 * package of major version DECAL_FORMAT_VERSION_MAJOR and any minor version
 * opens; DECAL_FORMAT_VERSION_MINOR is the newest minor it knows every
 * field of. Newer minors open too (they only add optional things). */
#define DECAL_FORMAT_VERSION_MAJOR 1
#define DECAL_FORMAT_VERSION_MINOR 3

/* The library's C API version, DECAL_C_API_VERSION's encoding. Compare its
 * major (value / 10000) with DECAL_C_API_VERSION_MAJOR. Never fails. */
DECAL_API uint32_t decal_version(void);
/* The library's version as text, "1.0.0". Static storage. Never fails. */
DECAL_API const char* decal_version_string(void);
/* The package format version the library reads, DECAL_FORMAT_VERSION_*'s
 * values for the library actually loaded. Either pointer may be NULL. */
DECAL_API void decal_format_version(uint32_t* major, uint32_t* minor);

/* Status codes. Values are part of the ABI. */
typedef enum decal_status {
  DECAL_OK = 0,
  /* A NULL pointer where one is required, an unknown flag bit, a blob index
   * out of range, a path or size the platform cannot represent. */
  DECAL_ERROR_INVALID_ARGUMENT = 1,
  /* The file cannot be opened or read, or is not a regular file (a FIFO, a
   * device or a directory is refused before a byte is read). */
  DECAL_ERROR_IO = 2,
  /* The bytes are not a valid package: bad magic, checksum, size, offset,
   * codec, zstd frame, reserved field, index (formats/SPEC.md
   * "Validation" and "Index constraints"). */
  DECAL_ERROR_FORMAT = 3,
  /* A package whose major version is not DECAL_FORMAT_VERSION_MAJOR, or
   * with a required flag this library does not know. */
  DECAL_ERROR_UNSUPPORTED_VERSION = 4,
  /* No blob of that name or id. */
  DECAL_ERROR_NOT_FOUND = 5,
  /* The caller's buffer is smaller than the blob; the needed size is
   * returned. */
  DECAL_ERROR_BUFFER_TOO_SMALL = 6,
  /* Memory for the package could not be allocated. */
  DECAL_ERROR_OUT_OF_MEMORY = 7,
  /* A failure the library did not expect (a bug): please report it. */
  DECAL_ERROR_INTERNAL = 8
} decal_status;

/* Size of decal_error.message, the terminating NUL included. */
#define DECAL_ERROR_MESSAGE_SIZE 512

/* What went wrong, written by the call it is passed to. */
typedef struct decal_error {
  int32_t code;                           /* a decal_status */
  char message[DECAL_ERROR_MESSAGE_SIZE]; /* NUL-terminated; "" on success */
} decal_error;

/* The name of a status, "DECAL_ERROR_FORMAT"; "unknown" for a value not in
 * decal_status. Static storage. Never fails. */
DECAL_API const char* decal_status_name(int32_t status);

/* Element types of a blob (formats/SPEC.md "Element types"; the numbers are
 * the format's). A blob of an unknown type is refused at open. */
typedef enum decal_element_type {
  DECAL_ELEMENT_U8 = 1,
  DECAL_ELEMENT_U32 = 2,
  DECAL_ELEMENT_I32 = 3,
  DECAL_ELEMENT_F32 = 4,
  DECAL_ELEMENT_IVEC2 = 5,
  DECAL_ELEMENT_UVEC2 = 6,
  DECAL_ELEMENT_IVEC4 = 7,
  DECAL_ELEMENT_UVEC4 = 8,
  DECAL_ELEMENT_VEC2 = 9,
  DECAL_ELEMENT_VEC4 = 10,
  DECAL_ELEMENT_RECORD = 11 /* a struct of formats/SPEC.md "Records" */
} decal_element_type;

/* How a blob is stored in the file (formats/SPEC.md "Codecs"). */
typedef enum decal_codec { DECAL_CODEC_NONE = 0, DECAL_CODEC_ZSTD = 1 } decal_codec;

/* An open, fully validated package. Opaque. */
typedef struct decal_package decal_package;

/* Bits of decal_open_options.flags. */
/* Read the file into memory instead of mapping it (decal_open_file only;
 * a mapped file must not be truncated while the package is open). */
#define DECAL_OPEN_NO_MMAP 0x1u
/* Skip the index check (formats/SPEC.md "Index constraints": every index
 * inside the blob it indexes, every range inside its list). Only for
 * packages already verified, e.g. by `decalprep verify`: without the
 * check, a hostile package's indices can point outside its blobs. */
#define DECAL_OPEN_SKIP_INDEX_CHECK 0x2u

/* How to open a package. Zero-initialise it ({0}) and set what you need;
 * a NULL options pointer means all defaults. */
typedef struct decal_open_options {
  uint32_t flags;        /* DECAL_OPEN_* bits; any other bit is refused */
  uint32_t reserved;     /* must be 0 */
  uint64_t max_raw_size; /* refuse packages whose blobs decode to more bytes
                            than this; 0: the default, 64 GiB */
} decal_open_options;

/* Opens and validates the package at `path` (a NUL-terminated file system
 * path, UTF-8 on systems whose paths are bytes): the header, blob table
 * and metadata checksums, every blob's placement, checksum and decoding,
 * and, unless DECAL_OPEN_SKIP_INDEX_CHECK, every index. Compressed blobs
 * are decoded now, so later calls do no work beyond copying. An
 * uncompressed package is mapped (unless DECAL_OPEN_NO_MMAP), else read.
 * On success *out is a new package (decal_close it) and DECAL_OK is
 * returned. On failure *out is NULL (when out is not NULL) and the status
 * says why: DECAL_ERROR_INVALID_ARGUMENT (NULL path or out, unknown flag
 * bits, nonzero reserved), DECAL_ERROR_IO, DECAL_ERROR_FORMAT,
 * DECAL_ERROR_UNSUPPORTED_VERSION, DECAL_ERROR_OUT_OF_MEMORY. */
DECAL_API decal_status decal_open_file(const char* path, const decal_open_options* options,
                                       decal_package** out, decal_error* error);

/* As decal_open_file, over `size` bytes at `data`. The bytes are copied
 * before anything is read, so they need not outlive the call and need not
 * be aligned; they must not change during the call. `data` may be NULL
 * when size is 0 (such a package is refused as DECAL_ERROR_FORMAT).
 * DECAL_OPEN_NO_MMAP is accepted and has no effect. */
DECAL_API decal_status decal_open_memory(const void* data, size_t size,
                                         const decal_open_options* options, decal_package** out,
                                         decal_error* error);

/* Destroys a package and everything it handed out. NULL is allowed and
 * does nothing. */
DECAL_API void decal_close(decal_package* package);

/* The package's format version, from its header. Either out-pointer may be
 * NULL. DECAL_ERROR_INVALID_ARGUMENT when package is NULL. */
DECAL_API decal_status decal_package_version(const decal_package* package, uint32_t* major,
                                             uint32_t* minor, decal_error* error);

/* The header's flags word (formats/SPEC.md "Flags"); 0 for a NULL package. */
DECAL_API uint32_t decal_package_flags(const decal_package* package);

/* The metadata JSON text (formats/SPEC.md "Metadata"): UTF-8, NUL-terminated
 * by the library (the NUL is not part of the package). *size, when size is
 * not NULL, gets its length in bytes without the NUL. Owned by the package.
 * DECAL_ERROR_INVALID_ARGUMENT when package or text is NULL; then *text is
 * not written. */
DECAL_API decal_status decal_metadata(const decal_package* package, const char** text, size_t* size,
                                      decal_error* error);

/* The number of blobs in the blob table (unknown ids included); 0 for a
 * NULL package. Blob indices run from 0 to this count - 1, in file order. */
DECAL_API uint32_t decal_blob_count(const decal_package* package);

/* One blob-table entry, as decal_blob_info fills it. */
typedef struct decal_blob_info {
  /* Wide fields first: no padding between fields on any platform. */
  uint64_t count;                /* elements */
  uint64_t raw_size;             /* decoded bytes: count * stride */
  uint64_t stored_size;          /* bytes in the file */
  uint32_t index;                /* position in the blob table */
  uint32_t id;                   /* blob id (formats/SPEC.md "Blob catalogue") */
  uint32_t element_type;         /* a decal_element_type */
  uint32_t stride;               /* bytes per element (std430) */
  uint32_t codec;                /* a decal_codec: how it is stored */
  uint32_t known;                /* 1 when this library knows the id, else 0 */
  const char* name;              /* "line_vertices"; owned by the package */
  const char* element_type_name; /* "ivec2", as SPEC.md writes it; static */
  const char* codec_name;        /* "none" or "zstd"; static */
} decal_blob_info;

/* Fills *info with blob `index`. DECAL_ERROR_INVALID_ARGUMENT when package
 * or info is NULL or index >= decal_blob_count; then *info is not written. */
DECAL_API decal_status decal_blob_info_at(const decal_package* package, uint32_t index,
                                          decal_blob_info* info, decal_error* error);

/* Finds the blob named `name` (NUL-terminated, compared byte for byte, as
 * the blob table stores it) and stores its index in *index.
 * DECAL_ERROR_NOT_FOUND when the package has none (then *index is not
 * written); DECAL_ERROR_INVALID_ARGUMENT on a NULL argument. */
DECAL_API decal_status decal_find_blob(const decal_package* package, const char* name,
                                       uint32_t* index, decal_error* error);

/* As decal_find_blob, by blob id (the first entry with that id). */
DECAL_API decal_status decal_find_blob_id(const decal_package* package, uint32_t id,
                                          uint32_t* index, decal_error* error);

/* Copies blob `index`, decoded, into the caller's `buffer` of `capacity`
 * bytes: raw_size bytes, little-endian elements of its stride (std430, as
 * a GPU storage buffer takes them). Once package and index are valid,
 * *needed (when needed is not NULL) gets raw_size, whatever else happens:
 * also on DECAL_ERROR_BUFFER_TOO_SMALL, so a first call with capacity 0
 * asks for the size. buffer may be NULL when capacity is 0.
 * Returns DECAL_OK for an empty blob (raw_size 0) whatever the capacity;
 * DECAL_ERROR_BUFFER_TOO_SMALL, writing nothing into buffer, when
 * capacity < raw_size; DECAL_ERROR_INVALID_ARGUMENT (*needed not written)
 * on a NULL package or an index out of range, and (*needed written) on a
 * NULL buffer with capacity > 0. On success buffer's first raw_size bytes
 * are the blob and the rest is left alone. */
DECAL_API decal_status decal_blob_read(const decal_package* package, uint32_t index, void* buffer,
                                       size_t capacity, size_t* needed, decal_error* error);

/* The decoded bytes of blob `index` without a copy: *data points at
 * raw_size bytes owned by the package (aligned to 4 bytes at least), valid
 * until decal_close; NULL with *size 0 for an empty blob. Neither pointer
 * is written on failure (DECAL_ERROR_INVALID_ARGUMENT on a NULL argument or
 * an index out of range). */
DECAL_API decal_status decal_blob_data(const decal_package* package, uint32_t index,
                                       const void** data, size_t* size, decal_error* error);

#ifdef __cplusplus
} /* extern "C" */
#endif

/* NOLINTEND(modernize-use-using,modernize-deprecated-headers) */

#endif /* DECAL_DECAL_H */
