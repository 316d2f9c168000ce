// errors.js — the error every refusal of a package or tileset throws.

/** A package or tileset that breaks the format; the message says where. */
export class FormatError extends Error {
  /** @param {string} message */
  constructor(message) {
    super(message);
    this.name = "FormatError";
  }
}
