/** The source face (GRID speaker 7), the one the recorded track drives. */
export const source: URL;
/** Every face by name: the source and four targets. */
export const faces: Readonly<{ spk07: URL; spk02: URL; spk03: URL; spk06: URL; spk10: URL }>;
/** The four target faces, in the demo's order. */
export const targets: readonly URL[];
/** Speaker 7's unseen clip as source parameters (`[{ pose, shape, appearance }, ...]`). */
export const track: Readonly<{ url: URL; fps: number }>;
/** The attribution these faces need wherever they are shown (CC BY 4.0). */
export const credits: string;
