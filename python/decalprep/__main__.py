"""python3 -m decalprep PACKAGE [--verify] [--blob NAME]

Prints a package as JSON: header, blob table entries, metadata and the
decoded elements (non-finite floats as null). Exit 0 when the package is
valid, 1 with a message on stderr when it is not, 2 on a usage error.
--verify adds SPEC.md "Index constraints" and the metadata checks of
`decalprep verify`.
"""

import json
import sys

from . import spec_reader as sr


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    verify = "--verify" in argv
    argv = [a for a in argv if a != "--verify"]
    only = None
    if "--blob" in argv:
        k = argv.index("--blob")
        if k + 1 >= len(argv):
            sys.stderr.write("decalprep: --blob needs a name\n")
            return 2
        only = argv[k + 1]
        del argv[k:k + 2]
    if len(argv) != 1:
        sys.stderr.write("usage: python3 -m decalprep PACKAGE [--verify] [--blob NAME]\n")
        return 2
    try:
        p = sr.read_file(argv[0])
    except (sr.FormatError, OSError) as e:
        sys.stderr.write("decalprep: %s\n" % e)
        return 1
    if verify:
        errs = sr.check_indices(p) + sr.check_metadata(p)
        if errs:
            sys.stderr.write("decalprep: %s: %s\n" % (argv[0], "; ".join(errs)))
            return 1
    json.dump(sr.to_json(p, only), sys.stdout, separators=(",", ":"), allow_nan=False)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
