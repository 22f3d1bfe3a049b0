{{/* The release's base name. */}}
{{- define "vademecum.fullname" -}}
{{- if contains .Chart.Name .Release.Name -}}
{{- .Release.Name | trunc 40 | trimSuffix "-" -}}
{{- else -}}
{{- printf "%s-%s" .Release.Name .Chart.Name | trunc 40 | trimSuffix "-" -}}
{{- end -}}
{{- end -}}

{{/* Labels every object carries. */}}
{{- define "vademecum.labels" -}}
app.kubernetes.io/name: {{ .Chart.Name }}
app.kubernetes.io/instance: {{ .Release.Name }}
app.kubernetes.io/version: {{ .Chart.AppVersion | quote }}
app.kubernetes.io/managed-by: {{ .Release.Service }}
helm.sh/chart: {{ printf "%s-%s" .Chart.Name .Chart.Version }}
{{- end -}}

{{/* Selector labels of one component (fleet, device, build). */}}
{{- define "vademecum.selector" -}}
app.kubernetes.io/name: {{ .root.Chart.Name }}
app.kubernetes.io/instance: {{ .root.Release.Name }}
app.kubernetes.io/component: {{ .component }}
{{- end -}}

{{/* The image, by digest when one is given. */}}
{{- define "vademecum.image" -}}
{{- if .Values.image.digest -}}
{{ .Values.image.repository }}@{{ .Values.image.digest }}
{{- else -}}
{{ .Values.image.repository }}:{{ .Values.image.tag }}
{{- end -}}
{{- end -}}

{{/* The headless Service's name: the fleet pods' DNS domain. */}}
{{- define "vademecum.headless" -}}
{{ include "vademecum.fullname" . }}-pods
{{- end -}}

{{/* The image's user: distroless nonroot, the same UID/GID for the server and the bridge
     (iceoryx2's shared-memory files are 0600). */}}
{{- define "vademecum.podSecurity" -}}
runAsNonRoot: true
runAsUser: 65532
runAsGroup: 65532
fsGroup: 65532
seccompProfile:
  type: RuntimeDefault
{{- end -}}

{{- define "vademecum.containerSecurity" -}}
allowPrivilegeEscalation: false
readOnlyRootFilesystem: true
runAsNonRoot: true
runAsUser: 65532
runAsGroup: 65532
capabilities:
  drop: ["ALL"]
{{- end -}}

{{/* Environment of a server container: its pod's name and namespace, and the tokens. */}}
{{- define "vademecum.serverEnv" -}}
- name: POD_NAME
  valueFrom:
    fieldRef:
      fieldPath: metadata.name
- name: POD_NAMESPACE
  valueFrom:
    fieldRef:
      fieldPath: metadata.namespace
- name: VADEMECUM_LOG
  value: info
{{- end -}}

{{/* The server's probes (Kubernetes' native gRPC probe on grpc.health.v1) and its preStop
     drain: no new session, then wait for the running ones up to drainSeconds. */}}
{{- define "vademecum.serverLifecycle" -}}
ports:
  - name: grpc
    containerPort: 50051
    protocol: TCP
  - name: metrics
    containerPort: 9100
    protocol: TCP
readinessProbe:
  grpc:
    port: 50051
  periodSeconds: 5
livenessProbe:
  grpc:
    port: 50051
  periodSeconds: 10
  failureThreshold: 6
lifecycle:
  preStop:
    exec:
      command: ["/usr/local/bin/vademecum", "drain", "--addr", "http://127.0.0.1:50051", "--wait", "{{ .Values.fleet.drainSeconds }}", "--tokens-file", "/var/run/secrets/vademecum/tokens"]
{{- end -}}

{{/* The bundle claim's mounts: bundles, scenes and meshes, read-only. */}}
{{- define "vademecum.dataMounts" -}}
- name: bundles
  mountPath: /var/lib/vademecum/bundles
  readOnly: true
- name: bundles
  mountPath: /var/lib/vademecum/scenes
  subPath: {{ .Values.bundles.scenesSubPath }}
  readOnly: true
- name: bundles
  mountPath: /var/lib/vademecum/meshes
  subPath: {{ .Values.bundles.meshesSubPath }}
  readOnly: true
- name: tmp
  mountPath: /tmp
- name: tokens
  mountPath: /var/run/secrets/vademecum
  readOnly: true
{{- if .Values.bundles.source }}
- name: bundle-cache
  mountPath: /var/cache/vademecum
{{- end }}
{{- end -}}

{{- define "vademecum.dataVolumes" -}}
- name: bundles
  persistentVolumeClaim:
    claimName: {{ .Values.bundles.claimName }}
    readOnly: true
- name: tmp
  emptyDir:
    medium: Memory
    sizeLimit: 64Mi
- name: tokens
  secret:
    secretName: {{ .Values.tokens.secretName }}
    defaultMode: 0440
    items:
      - key: {{ .Values.tokens.key }}
        path: tokens
{{- if .Values.bundles.source }}
- name: bundle-cache
  emptyDir:
    sizeLimit: {{ .Values.bundles.cacheSize }}
{{- end }}
{{- end -}}

{{/* `vademecum serve` flags shared by every server pod. */}}
{{- define "vademecum.serveArgs" -}}
- serve
- --listen
- 0.0.0.0:50051
- --metrics
- 0.0.0.0:9100
- --metrics-public
- --bundle-root
- /var/lib/vademecum/bundles
- --scene-root
- /var/lib/vademecum/scenes
- --mesh-root
- /var/lib/vademecum/meshes
- --tokens-file
- /var/run/secrets/vademecum/tokens
{{- if .Values.bundles.source }}
- --bundle-store
- /var/cache/vademecum/store
- --bundle-source
- {{ .Values.bundles.source | quote }}
{{- else }}
- --bundle-store
- /var/lib/vademecum/bundles/{{ .Values.bundles.storeSubPath }}
{{- end }}
- --name
- $(POD_NAME)
- --max-sessions
- {{ .Values.fleet.maxSessionsPerPod | quote }}
- --max-tick-load
- {{ .Values.fleet.maxTickLoad | quote }}
{{- end -}}
