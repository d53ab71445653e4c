// Validates Kubernetes manifests against the API's JSON schemas, offline:
// each document's apiVersion and kind pick its model from the npm package
// kubernetes-models (schemas of the Kubernetes OpenAPI spec, checked with
// ajv). Used by deploy/validate_manifests.sh.
//
//   node validate.mjs FILE.yaml...   (exit 1 when a document is invalid)
import fs from 'fs';
import * as yaml from 'js-yaml';

let failed = 0;
for (const file of process.argv.slice(2)) {
  const docs = yaml.loadAll(fs.readFileSync(file, 'utf8')).filter(Boolean);
  for (const doc of docs) {
    const where = `${file}: ${doc.kind}/${doc.metadata?.name}`;
    try {
      const [group, version] = doc.apiVersion.includes('/') ? doc.apiVersion.split('/')
                                                            : ['', doc.apiVersion];
      const models = await import(`kubernetes-models/${group ? group + '/' : ''}${version}`);
      if (!models[doc.kind]) throw new Error(`no kind ${doc.kind} in ${doc.apiVersion}`);
      new models[doc.kind](doc).validate();
      console.log(`${where}: valid`);
    } catch (e) {
      failed++;
      console.log(`${where}: INVALID: ${e.message}`);
    }
  }
}
process.exit(failed ? 1 : 0);
