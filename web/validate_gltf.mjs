// The Khronos glTF validator (npm gltf-validator, validateBytes) on each GLB given; prints one JSON
// line per file {file, errors, warnings, infos, messages (the errors' codes and pointers)}.
import fs from 'node:fs';
import path from 'node:path';
import validator from 'gltf-validator';

for (const file of process.argv.slice(2)) {
  const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
    uri: path.basename(file), maxIssues: 200,
    externalResourceFunction: (uri) => Promise.resolve(new Uint8Array(fs.readFileSync(path.join(path.dirname(file), decodeURIComponent(uri))))),
  });
  const errs = report.issues.messages.filter((m) => m.severity <= (process.env.SEVERITY ? Number(process.env.SEVERITY) : 0)).map((m) => `${m.code} ${m.pointer || ''}`);
  console.log(JSON.stringify({ file, errors: report.issues.numErrors, warnings: report.issues.numWarnings,
                               infos: report.issues.numInfos, messages: errs.slice(0, 20) }));
}
